//! The splatting pipeline against its f64 CPU twin: random scenes, the demo
//! city and the real trained scene, every channel, with outputs pre-filled
//! with a NaN sentinel; extremes give finite outputs and no validation message.

#![allow(clippy::unwrap_used, clippy::expect_used, reason = "a failed unwrap is a failed test")]

use glam::Vec3;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use srug::gpu::ash::vk;
use srug::gpu::{Device, TexelFormat};
use srug::io::read_ply;
use srug::scene::activate::GpuScene;
use srug::scene::demo::{demo_city, DemoOptions};
use srug::scene::order::SceneOrder;
use srug::scene::{Camera, Scene};
use srug::splat::backward::BlendGrads;
use srug::splat::cpu::{
    blend_work, pack_features, preprocess_one, render_cpu, tile_row_span, unpack_features, CpuSplat,
};
use srug::splat::{
    cameras_per_batch, default_blend_pixels, default_pixel_reach, default_two_splats_per_step, default_window_fetch,
    BlendVariant, Channels, DepthKey, GBuffer, NormalSource, SplatSettings, Splatter, TileBounds, BATCH_BYTES,
    BLEND_PIXELS, DEFAULT_CHUNK_LENGTH, DEFAULT_MEDIAN_COVERAGE, DEFAULT_TILE, FRAMES_PER_SUBMISSION, MAX_CHUNK_LENGTH,
    SPLAT_STAGES, TILE_SIZES,
};
use srug::splat::{Channel, PerChannel};
use srug_tests::{
    assert_no_validation_messages, device, move_scene, psnr, random_scene, save_comparison, NAN_SENTINEL,
};

const NAN: u32 = NAN_SENTINEL;
/// rgb must agree with the CPU twin to this PSNR (peak 1).
const MIN_PSNR_DB: f64 = 50.0;
/// Largest error allowed in alpha, relative to 1.
const ALPHA_TOLERANCE: f64 = 2e-3;

/// Compares every channel; the tolerance of premultiplied channels scales
/// with their largest value.
fn compare(gpu: &GBuffer, cpu: &GBuffer, label: &str) {
    compare_with(gpu, cpu, label, false);
}

/// [`compare`]; with `stop_flips`, channels other than rgb (checked by PSNR)
/// may exceed the tolerance at 1 pixel in 1000: where a pixel's transmittance
/// lands on the 1e-4 stop threshold, or a splat's α on the 1/255 cutoff, f32
/// and f64 can take one splat more or less (seen through the fisheye at one
/// pixel of 25,600, T = 1.27e-4; through the thin-prism fisheye at 2 of 33,792,
/// alpha 3e-3 ≈ T/255).
fn compare_with(gpu: &GBuffer, cpu: &GBuffer, label: &str, stop_flips: bool) {
    for ((name, g, k), (_, c, _)) in gpu.channels().into_iter().zip(cpu.channels()) {
        assert!(g.iter().all(|v| v.is_finite()), "{label}: {name} has non-finite values (unwritten sentinel?)");
        let (ok, what) = match name {
            "rgb" => {
                let p = psnr(g, c);
                (p >= MIN_PSNR_DB, format!("PSNR {p:.1} dB < {MIN_PSNR_DB}"))
            }
            _ => {
                let scale = c.iter().fold(1.0f64, |m, v| m.max(f64::from(v.abs())));
                let tol = ALPHA_TOLERANCE * scale;
                let err = g.iter().zip(c).map(|(a, b)| (f64::from(*a) - f64::from(*b)).abs()).fold(0.0, f64::max);
                // Median depth jumps where a near-tie flips which splat crosses T = 0.5: count outliers instead.
                if name == "median_depth" || stop_flips {
                    let bad = g.iter().zip(c).filter(|(a, b)| (f64::from(**a) - f64::from(**b)).abs() > tol).count();
                    (bad * 1000 <= g.len(), format!("{bad} of {} pixels differ by more than {tol:.2e}", g.len()))
                } else {
                    (err <= tol, format!("max error {err:.3e} > {tol:.3e}"))
                }
            }
        };
        if !ok {
            let saved = save_comparison(&format!("{label}_{name}"), gpu.width, gpu.height, k, g, c);
            panic!("{label}: {name}: {what} (images: {saved})");
        }
    }
    // The top Gaussian is an index, exact: it may differ only where two splats' weights nearly
    // tie (f32 against f64), as rarely as median depth's flips.
    assert_eq!(gpu.top_gaussian.is_some(), cpu.top_gaussian.is_some(), "{label}: top_gaussian kept by one only");
    if let (Some(g), Some(c)) = (&gpu.top_gaussian, &cpu.top_gaussian) {
        assert!(!g.contains(&NAN), "{label}: top_gaussian has unwritten pixels");
        let bad = g.iter().zip(c).filter(|(a, b)| a != b).count();
        assert!(bad * 1000 <= g.len(), "{label}: top_gaussian differs from the twin at {bad} of {} pixels", g.len());
        let none = |v: &[u32]| v.iter().filter(|x| **x == u32::MAX).count();
        assert!(none(g).abs_diff(none(c)) * 1000 <= g.len(), "{label}: empty pixels {} vs {}", none(g), none(c));
    }
}

fn render_both(
    d: &Device,
    splatter: &mut Splatter,
    scene: &Scene,
    camera: &Camera,
    settings: &SplatSettings,
    label: &str,
) -> GBuffer {
    let gpu_scene = GpuScene::upload(d, scene).unwrap();
    let (out, stats) = splatter.render(&gpu_scene, camera, settings).unwrap();
    let gpu = out.read(d).unwrap();
    let cpu = render_cpu(scene, camera, settings);
    compare(&gpu, &cpu, label);
    eprintln!("{label}: {} pairs, {} key bits", stats.pairs, stats.key_bits);
    gpu
}

/// Every blend variant the device runs (subgroup loads where it has subgroup ballot).
fn blend_variants(d: &Device) -> Vec<BlendVariant> {
    let mut variants = vec![BlendVariant::PerPixel, BlendVariant::SharedBatches];
    if d.info().subgroup_ballot {
        variants.push(BlendVariant::SubgroupLoads);
    }
    variants
}

fn all_settings() -> SplatSettings {
    SplatSettings {
        background: [0.2, 0.3, 0.4],
        channels: Channels { top_gaussian: true, ..Channels::ALL },
        normal_source: NormalSource::Stored,
        prefill: Some(NAN),
        rgb: true,
        sh_degree: None,
        tile: DEFAULT_TILE,
        tile_bounds: TileBounds::default(),
        surface_depth: false,
        median_coverage: DEFAULT_MEDIAN_COVERAGE,
        packed_features: false,
        compact_splats: false,
    }
}

/// Smallest σ = ½dᵀQd of splat `s` over the square [x0, x1] × [y0, y1]
/// (exact: 0 when the centre is inside, else the least of each edge's minimum).
fn least_sigma(s: &CpuSplat, x0: f64, x1: f64, y0: f64, y1: f64) -> f64 {
    let [a, b, c] = s.conic;
    let (lx, hx, ly, hy) = (x0 - s.mean.x, x1 - s.mean.x, y0 - s.mean.y, y1 - s.mean.y);
    if lx <= 0.0 && hx >= 0.0 && ly <= 0.0 && hy >= 0.0 {
        return 0.0;
    }
    let q = |x: f64, y: f64| 0.5 * (a * x * x + c * y * y) + b * x * y;
    let on_x = [lx, hx].map(|x| q(x, (-b * x / c).clamp(ly, hy)));
    let on_y = [ly, hy].map(|y| q((-b * y / a).clamp(lx, hx), y));
    on_x.into_iter().chain(on_y).fold(f64::INFINITY, f64::min)
}

#[test]
fn ellipse_tile_bounds_keep_every_tile_a_splat_reaches_and_little_else() {
    // CPU only: the span against the exact test, on random splats from round to
    // 1000:1 elongated, 0.3 to 10⁴ px² per axis, opacity 10⁻³ to 1.
    let mut rng = Pcg64Mcg::seed_from_u64(33);
    let (mut reached, mut kept, mut rect_tiles, mut splats_checked) = (0u64, 0u64, 0u64, 0);
    for tile in TILE_SIZES {
        let tiles = 4096 / tile;
        for _ in 0..3000 {
            let l1: f64 = 10f64.powf(rng.random_range(-0.5..4.0));
            let l2: f64 = l1 / 10f64.powf(rng.random_range(0.0..3.0));
            let (l1, l2) = (l1.max(0.3), l2.max(0.3));
            let angle: f64 = rng.random_range(0.0..std::f64::consts::PI);
            let (sn, cs) = angle.sin_cos();
            let (a, b, c) = (l1 * cs * cs + l2 * sn * sn, (l1 - l2) * sn * cs, l1 * sn * sn + l2 * cs * cs);
            let det = a * c - b * b;
            let mean = glam::DVec2::new(rng.random_range(-100.0..4200.0), rng.random_range(-100.0..4200.0));
            let radius = (3.0 * l1.max(l2).sqrt()).ceil();
            let t = f64::from(tile);
            let lo = ((mean - radius) / t).floor().clamp(glam::DVec2::ZERO, glam::DVec2::splat(f64::from(tiles)));
            let hi =
                (((mean + radius) / t).floor() + 1.0).clamp(glam::DVec2::ZERO, glam::DVec2::splat(f64::from(tiles)));
            let s = CpuSplat {
                mean,
                depth: 1.0,
                opacity: 10f64.powf(rng.random_range(-3.0..0.0)),
                conic: [c / det, -b / det, a / det],
                radius,
                color: glam::DVec3::ZERO,
                rect: [lo.x as u32, lo.y as u32, hi.x as u32, hi.y as u32],
                features: [0.0; 10],
                wrap_period: 0.0,
                depth_slope: [0.0; 2],
                orthographic: false,
            };
            splats_checked += 1;
            for ty in s.rect[1]..s.rect[3] {
                let (x0, x1) = tile_row_span(&s, ty, tile);
                assert!(s.rect[0] <= x0 && x0 <= x1 && x1 <= s.rect[2], "{s:?}: row {ty} span {x0}..{x1}");
                for tx in s.rect[0]..s.rect[2] {
                    let (fx, fy) = (f64::from(tx) * t, f64::from(ty) * t);
                    let sigma = least_sigma(&s, fx, fx + t, fy, fy + t);
                    let reaches = s.opacity * (-sigma).exp() >= 1.0 / 255.0;
                    let listed = (x0..x1).contains(&tx);
                    assert!(listed || !reaches, "tile {tile}: ({tx}, {ty}) reaches α ≥ 1/255 but is not listed: {s:?}");
                    reached += u64::from(reaches);
                    kept += u64::from(listed);
                    rect_tiles += 1;
                }
            }
        }
    }
    // The widening (1% of r², 0.01 px) and the ill-conditioned fallback add few tiles.
    let extra = kept as f64 / reached as f64 - 1.0;
    eprintln!(
        "{splats_checked} splats: {rect_tiles} rectangle tiles, {reached} reach α ≥ 1/255, {kept} listed (+{:.2}%)",
        100.0 * extra
    );
    assert!(extra < 0.03, "ellipse bounds list {:.2}% more tiles than reach the splat", 100.0 * extra);
    assert!((kept as f64) < 0.8 * rect_tiles as f64, "ellipse bounds should drop many rectangle tiles");
}

#[test]
fn ellipse_and_rectangle_tile_bounds_give_the_same_image() {
    let d = device();
    let mut splatter = Splatter::new(&d).unwrap();
    // Whole lists: the two bounds' lists differ in length, so the split blend
    // (on GPUs by default) could split one and not the other, which rounds differently.
    splatter.set_chunk_length(0).unwrap();
    let city = demo_city(&DemoOptions { seed: 7, gaussians: 60_000, sh_degree: 1 }).unwrap();
    let mut faint = random_scene(4000, 1, 44, 2.0);
    // Opacities from 0.0003 to 0.5: many splats reach 1/255 only near their centre, some nowhere.
    for (i, o) in faint.opacity_logits.iter_mut().enumerate() {
        *o = -8.0 + 8.0 * (i % 17) as f32 / 16.0;
    }
    let look = |w, h| Camera::look_at(Vec3::new(0.0, -6.0, 0.5), Vec3::ZERO, Vec3::Z, 70.0, w, h).unwrap();
    let ortho =
        Camera::orthographic(Vec3::new(0.0, -6.0, 0.0), Vec3::Y, Vec3::Z, 5.0, 3.0, 160, 96, 0.01, 20.0).unwrap();
    // The random scenes have no materials: depth, median depth and normal besides rgb and alpha.
    let geometric = SplatSettings {
        channels: Channels { depth: true, median_depth: true, normal: true, ..Channels::default() },
        ..all_settings()
    };
    let cases = [
        ("demo", &city.scene, city.cameras[1].resized(352, 96), all_settings()),
        ("faint", &faint, look(203, 77), geometric),
        ("faint_orthographic", &faint, ortho, geometric),
    ];
    for (label, scene, cam, base) in cases {
        let gpu_scene = GpuScene::upload(&d, scene).unwrap();
        for tile in TILE_SIZES {
            let mut runs = Vec::new();
            for tile_bounds in [TileBounds::Rectangle, TileBounds::Ellipse] {
                let settings = SplatSettings { tile, tile_bounds, ..base };
                let label = format!("{label}_tile_{tile}_{tile_bounds:?}");
                let (out, stats) = splatter.render(&gpu_scene, &cam, &settings).unwrap();
                let gpu = out.read(&d).unwrap();
                compare(&gpu, &render_cpu(scene, &cam, &settings), &label);
                runs.push((gpu, stats.pairs));
            }
            let ((rect, rect_pairs), (ellipse, ellipse_pairs)) = (&runs[0], &runs[1]);
            // The GPU lists what the twin's f64 span lists, but for f32 rounding at the widened bound.
            let twin_pairs: u64 = (0..scene.len())
                .filter_map(|i| preprocess_one(scene, i, &cam, NormalSource::Stored, tile))
                .flat_map(|s| (s.rect[1]..s.rect[3]).map(move |ty| tile_row_span(&s, ty, tile)))
                .map(|(x0, x1)| u64::from(x1 - x0))
                .sum();
            assert!(
                ellipse_pairs.abs_diff(twin_pairs) <= 2 + twin_pairs / 1000,
                "{label} tile {tile}: GPU {ellipse_pairs} pairs, twin {twin_pairs}"
            );
            assert!(
                ellipse_pairs < rect_pairs,
                "{label} tile {tile}: {ellipse_pairs} ellipse pairs, {rect_pairs} rectangle"
            );
            let same =
                |a: &[f32], b: &[f32]| a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits());
            let (rc, ec) = (rect.channels(), ellipse.channels());
            let names = |c: &[(&'static str, &[f32], usize)]| c.iter().map(|x| x.0).collect::<Vec<_>>();
            assert_eq!(names(&rc), names(&ec), "{label} tile {tile}: the same channels");
            for ((name, r, _), (_, e, _)) in rc.iter().zip(&ec) {
                assert!(same(r, e), "{label} tile {tile}: {name} differs between bounds");
            }
            eprintln!("{label} tile {tile}: {rect_pairs} rectangle pairs, {ellipse_pairs} ellipse (twin {twin_pairs}), same image");
        }
    }
    assert_no_validation_messages(&d);
}

#[test]
fn capped_sh_degree_matches_cpu_twin_and_changes_colour() {
    let d = device();
    let mut splatter = Splatter::new(&d).unwrap();
    let scene = random_scene(3000, 3, 21, 2.0);
    let cam = Camera::look_at(Vec3::new(0.0, -6.0, 0.5), Vec3::ZERO, Vec3::Z, 70.0, 96, 64).unwrap();
    let base = SplatSettings { channels: Channels { depth: true, ..Channels::default() }, ..all_settings() };
    let full = render_both(&d, &mut splatter, &scene, &cam, &base, "sh_full");
    for degree in [0u32, 1, 2, 7] {
        let settings = SplatSettings { sh_degree: Some(degree), ..base };
        let capped = render_both(&d, &mut splatter, &scene, &cam, &settings, &format!("sh_cap_{degree}"));
        let changed = capped
            .rgb_values()
            .unwrap()
            .iter()
            .zip(full.rgb_values().unwrap())
            .filter(|(a, b)| (*a - *b).abs() > 1e-3)
            .count();
        if degree >= 3 {
            assert_eq!(capped.rgb, full.rgb, "a cap at or above the scene's degree changes nothing");
        } else {
            assert!(changed > 100, "SH degree {degree}: only {changed} values changed");
        }
        // The twin's truncated scene is the file's coefficients cut short, not re-fitted.
        assert_eq!(scene.with_sh_degree(degree.min(3)).sh.len(), 3000 * 3 * ((degree.min(3) as usize + 1).pow(2)));
    }
    assert_no_validation_messages(&d);
}

#[test]
fn every_tile_size_matches_cpu_twin_in_every_variant() {
    let d = device();
    let mut splatter = Splatter::new(&d).unwrap();
    let city = demo_city(&DemoOptions { seed: 7, gaussians: 30_000, sh_degree: 1 }).unwrap();
    // Not a multiple of any tile edge, so every kernel meets partial tiles.
    let cam = city.cameras[1].resized(203, 77);
    let gpu_scene = GpuScene::upload(&d, &city.scene).unwrap();
    let variants = blend_variants(&d);
    let mut by_tile = Vec::new();
    for tile in TILE_SIZES {
        let settings = SplatSettings { tile, ..all_settings() };
        for &variant in &variants {
            splatter.set_blend_variant(variant).unwrap();
            render_both(&d, &mut splatter, &city.scene, &cam, &settings, &format!("tile_{tile}_{variant:?}"));
        }
        // The subgroup-load blend also without its texel-buffer reads (the default keeps them).
        if d.info().subgroup_ballot {
            assert!(splatter.texel_blend(), "lavapipe has RGBA32F texel buffers, so they are the default");
            assert!(splatter.texel_preprocess(), "lavapipe has R32F texel buffers, so they are the default");
            let mesa_25 = d.info().is_lavapipe() && d.info().mesa_version().is_some_and(|(major, _)| major >= 25);
            let gpu = d.info().device_type != vk::PhysicalDeviceType::CPU;
            let expected = if mesa_25 {
                8
            } else if gpu {
                1
            } else {
                2
            };
            assert_eq!(splatter.blend_pixels(), expected, "default pixels per invocation on {}", d.info().driver);
            assert_eq!(splatter.pixel_reach(), mesa_25, "default per-pixel reach on {}", d.info().driver);
            assert_eq!(splatter.window_fetch(), mesa_25 || gpu, "default per-window fetch on {}", d.info().driver);
            assert_eq!(splatter.two_splats_per_step(), gpu, "default two splats a step on {}", d.info().driver);
            let chunk = if gpu { DEFAULT_CHUNK_LENGTH } else { 0 };
            assert_eq!(splatter.chunk_length(), chunk, "default split-blend chunk length on {}", d.info().driver);
            splatter.set_blend_variant(BlendVariant::SubgroupLoads).unwrap();
            splatter.set_texel_blend(false).unwrap();
            splatter.set_texel_preprocess(false).unwrap();
            render_both(&d, &mut splatter, &city.scene, &cam, &settings, &format!("tile_{tile}_address_reads"));
            splatter.set_texel_blend(true).unwrap();
            splatter.set_texel_preprocess(true).unwrap();
            // Every pixels-per-invocation setting of the texel blend (partial tiles leave
            // some of an invocation's pixels outside the image).
            for pixels in BLEND_PIXELS {
                splatter.set_blend_pixels(pixels).unwrap();
                render_both(&d, &mut splatter, &city.scene, &cam, &settings, &format!("tile_{tile}_pixels_{pixels}"));
            }
            splatter.set_blend_pixels(default_blend_pixels(d.info())).unwrap();
        }
        let (out, stats) = splatter.render(&gpu_scene, &cam, &settings).unwrap();
        by_tile.push((tile, out.read(&d).unwrap(), stats.pairs));
    }
    // Smaller tiles list each splat in more tiles, and the images agree closely:
    // only splat tails beyond the 3σ rectangle, cut at different tile edges, differ.
    for w in by_tile.windows(2) {
        let ((t0, g0, p0), (t1, g1, p1)) = (&w[0], &w[1]);
        assert!(p0 > p1, "tile {t0}: {p0} pairs, tile {t1}: {p1}");
        let p = psnr(g0.rgb_values().unwrap(), g1.rgb_values().unwrap());
        assert!(p > 60.0, "tiles {t0} and {t1} differ by PSNR {p:.1} dB");
        eprintln!("tiles {t0} and {t1}: {p0} and {p1} pairs, rgb PSNR {p:.1} dB");
    }
    for bad in [0u32, 3, 16] {
        let text = splatter.set_blend_pixels(bad).err().map(|e| e.to_string()).unwrap_or_default();
        assert!(text.contains(&format!("{bad} pixels per blend invocation: is not one of")), "{bad}: {text:?}");
    }
    for bad in [0u32, 4, 12, 64] {
        let e = splatter.render(&gpu_scene, &cam, &SplatSettings { tile: bad, ..all_settings() }).err();
        let text = e.map(|e| e.to_string()).unwrap_or_default();
        assert!(text.contains(&format!("tile size {bad}: is not one of")), "tile {bad}: {text:?}");
    }
    assert_no_validation_messages(&d);
}

/// Every channel's bits, for exact comparisons.
fn gbuffer_bits(g: &GBuffer) -> Vec<u32> {
    let mut bits: Vec<u32> = g.alpha.iter().map(|v| v.to_bits()).collect();
    bits.extend(g.rgb.iter().flatten().map(|v| v.to_bits()));
    for (_, values) in g.channels.iter() {
        bits.extend(values.iter().map(|v| v.to_bits()));
    }
    bits.extend(g.top_gaussian.iter().flatten());
    bits
}

#[test]
fn row_skipping_blend_is_bit_identical_to_reading_every_splat() {
    // The texel blend skips a splat for a subgroup whose blocks (half-tile
    // columns × row pairs) its α ≥ 1/255 ellipse misses (block masks in the
    // keys), and within a subgroup the pixels outside that ellipse on each
    // lane's row (`lane_row_reach`, with an upper bound of the log); the
    // device-address blend reads and evaluates every splat of the tile. Same
    // arithmetic in the same order, so any wrongly skipped splat changes
    // some bit. Elongated, rotated splats of every size (random scenes; faint
    // ones, opacities around 1/255, where the ellipse's r² is near 0) and
    // the demo street, every pixels-per-lane
    // layout (8 at 16-pixel tiles is the half-tile one); every tile size
    // carries masks at these sizes (at most 21 + 10 key bits). Each with
    // and without the per-window fetch (lanes fetch a window's wanted
    // splats, the subgroup hands them out), and with it two splats a loop
    // step, also with surface depths
    // (their slope rides in the colour texel) with and without rgb.
    let d = device();
    if !d.info().subgroup_ballot {
        eprintln!("skipping: the texel blend needs subgroup ballot");
        return;
    }
    let mut splatter = Splatter::new(&d).unwrap();
    // Whole lists: the split blend's chunks round differently (its own test below).
    splatter.set_chunk_length(0).unwrap();
    let city = demo_city(&DemoOptions { seed: 7, gaussians: 30_000, sh_degree: 1 }).unwrap();
    let street = (city.scene.clone(), city.cameras[1].resized(203, 77));
    let random = random_scene(6000, 1, 91, 2.0);
    let mut faint = random.clone();
    for (i, logit) in faint.opacity_logits.iter_mut().enumerate() {
        // Opacities 0.0015 to 0.011, either side of 1/255 (logit −5.54).
        *logit = -6.5 + 2.0 * (i % 101) as f32 / 100.0;
    }
    let close = Camera::look_at(Vec3::new(0.0, -4.0, 0.3), Vec3::ZERO, Vec3::Z, 80.0, 190, 110).unwrap();
    // The random scene has no materials: the channels it has.
    let geometric =
        Channels { depth: true, median_depth: true, normal: true, top_gaussian: true, ..Channels::default() };
    // Planes 10⁻³⁰ to 10³⁰ (a 24-bit depth key) and 260 tiles of 32 pixels: no room left.
    let wide = Camera { near: 1e-30, far: 1e30, ..city.cameras[1].resized(640, 416) };
    let unbounded = (city.scene.clone(), wide);
    let (mut checked_with_masks, mut checked_without) = (0, 0);
    let all = all_settings();
    let surface = SplatSettings { surface_depth: true, ..all };
    let surface_no_rgb = SplatSettings { rgb: false, ..surface };
    for (name, (scene, cam), base) in [
        ("street", street.clone(), all),
        ("street, surface depths", street.clone(), surface),
        ("street, surface depths, no rgb", street, surface_no_rgb),
        ("random", (random, close.clone()), SplatSettings { channels: geometric, ..all }),
        ("random, faint", (faint, close), SplatSettings { channels: geometric, ..all }),
        ("street, planes 1e-30 to 1e30", unbounded, all),
    ] {
        let gpu_scene = GpuScene::upload(&d, &scene).unwrap();
        for tile in TILE_SIZES {
            let settings = SplatSettings { tile, ..base };
            splatter.set_texel_blend(false).unwrap();
            let (everything, all_stats) = splatter.render(&gpu_scene, &cam, &settings).unwrap();
            assert!(!all_stats.row_masks, "{name} tile {tile}: only the texel blend skips rows");
            let everything = gbuffer_bits(&everything.read(&d).unwrap());
            splatter.set_texel_blend(true).unwrap();
            let layouts = BLEND_PIXELS.into_iter().flat_map(|p| [(p, false), (p, true)]);
            // Window fetch off, on, and on with two splats a step.
            let fetches = [(false, false), (true, false), (true, true)];
            for ((pixels, reach), (window, two)) in layouts.flat_map(|l| fetches.map(|f| (l, f))) {
                splatter.set_blend_pixels(pixels).unwrap();
                splatter.set_pixel_reach(reach);
                splatter.set_window_fetch(window);
                splatter.set_two_splats_per_step(two);
                let (skipping, stats) = splatter.render(&gpu_scene, &cam, &settings).unwrap();
                assert_eq!(
                    stats.row_masks,
                    stats.key_bits + tile <= 64,
                    "{name} tile {tile}: row masks where they fit the key"
                );
                checked_with_masks += usize::from(stats.row_masks);
                checked_without += usize::from(!stats.row_masks);
                let skipping = gbuffer_bits(&skipping.read(&d).unwrap());
                let differ = everything.iter().zip(&skipping).filter(|(a, b)| a != b).count();
                assert_eq!(
                    differ, 0,
                    "{name} tile {tile}, {pixels} pixels per invocation, pixel reach {reach}, window fetch {window}, \
                     two splats a step {two}: {differ} values differ"
                );
            }
        }
    }
    // Six scenes at three tile sizes, six blend settings per layout; only the planes 1e-30 to 1e30 at 32-pixel tiles leave no room.
    assert_eq!((checked_with_masks, checked_without), (102 * BLEND_PIXELS.len(), 6 * BLEND_PIXELS.len()));
    splatter.set_blend_pixels(default_blend_pixels(d.info())).unwrap();
    splatter.set_pixel_reach(default_pixel_reach(d.info()));
    splatter.set_window_fetch(default_window_fetch(d.info()));
    splatter.set_two_splats_per_step(default_two_splats_per_step(d.info()));
    assert_no_validation_messages(&d);
}

/// Every channel of `split` within `tolerance` (relative to the channel's
/// largest value) of `whole`, but at 1 pixel in 1000 (a pixel whose
/// transmittance lands on the 1e-4 stop or a median crossing on T = 0.5
/// can go either way when the product is rounded in another order); top
/// Gaussians equal there too.
fn assert_close_to(split: &GBuffer, whole: &GBuffer, tolerance: f64, label: &str) {
    for ((name, a, _), (_, b, _)) in split.channels().into_iter().zip(whole.channels()) {
        assert!(a.iter().all(|v| v.is_finite()), "{label}: {name} has non-finite values (unwritten sentinel?)");
        let scale = b.iter().fold(1.0f64, |m, v| m.max(f64::from(v.abs())));
        let bad = a.iter().zip(b).filter(|(x, y)| (f64::from(**x) - f64::from(**y)).abs() > tolerance * scale).count();
        assert!(
            bad * 1000 <= a.len(),
            "{label}: {name}: {bad} of {} values differ by more than {tolerance:e}",
            a.len()
        );
    }
    if let (Some(a), Some(b)) = (&split.top_gaussian, &whole.top_gaussian) {
        let bad = a.iter().zip(b).filter(|(x, y)| x != y).count();
        assert!(bad * 1000 <= a.len(), "{label}: top Gaussian differs at {bad} of {} pixels", a.len());
    }
}

#[test]
fn split_tile_lists_blend_as_one_walk_does() {
    // The split blend cuts each tile list longer than twice the chunk length
    // into chunks walked by workgroups of their own: a transmittance pass, a
    // blend of each chunk from the earlier chunks' product, a merge in list
    // order. Short chunks here (the default splits only on GPUs, at 1024) so
    // that most tiles split, walks cross many chunks, pixels stop (T < 1e-4)
    // in one chunk and the median crosses T = 0.5 in another; every channel,
    // surface depths (whose median a later chunk can move), no colour, a
    // panorama, stacks of opaque and of faint splats, every tile size,
    // pixels-per-lane layout and fetch. Against the CPU twin at its
    // tolerances, and against the whole-list blend, which rounds the same
    // products in another order, at 1e-5; the frame's chunk count too.
    let d = device();
    if !d.info().subgroup_ballot {
        eprintln!("skipping: the split blend is the texel blend's, which needs subgroup ballot");
        return;
    }
    const CHUNK: u32 = 24;
    let mut splatter = Splatter::new(&d).unwrap();
    let city = demo_city(&DemoOptions { seed: 7, gaussians: 30_000, sh_degree: 1 }).unwrap();
    let street = city.cameras[1].resized(203, 77);
    let random = random_scene(6000, 1, 91, 2.0);
    let close = Camera::look_at(Vec3::new(0.0, -4.0, 0.3), Vec3::ZERO, Vec3::Z, 80.0, 190, 110).unwrap();
    let geometric =
        Channels { depth: true, median_depth: true, normal: true, top_gaussian: true, ..Channels::default() };
    let all = all_settings();
    let surface = SplatSettings { surface_depth: true, ..all };
    // A full panorama (its lists wrap at the seam) and a frame without colour (the shadow maps').
    let panorama = lens_cameras(&city).into_iter().find(|(name, _)| *name == "equirectangular").unwrap().1;
    // 3000 splats stacked nearly on one spot: opaque ones (α 0.99: pixels done in the first
    // chunk, every later chunk skipped) and faint ones (α 0.005: done around the 1800th, deep in
    // the list; fringe pixels never).
    let stack = |logit: f32| {
        let mut scene = one_gaussian([0.0, 0.0, 0.0], -1.5, logit);
        for i in 1..3000 {
            let g = one_gaussian([0.2 * (i as f32 * 0.37).sin(), 0.001 * i as f32, 0.0], -1.5, logit);
            scene.means.extend(&g.means);
            scene.log_scales.extend(&g.log_scales);
            scene.rotations.extend(&g.rotations);
            scene.opacity_logits.extend(&g.opacity_logits);
            scene.sh.extend(&g.sh);
        }
        scene
    };
    let (opaque, faint) = (stack(8.0), stack((0.005f32 / 0.995).ln()));
    let mut checked = 0;
    for (name, scene, cam, base) in [
        ("street", &city.scene, &street, all),
        ("street, surface depths", &city.scene, &street, surface),
        ("street, no rgb", &city.scene, &street, SplatSettings { rgb: false, ..all }),
        ("street, median at 0.7", &city.scene, &street, SplatSettings { median_coverage: 0.7, ..surface }),
        ("panorama", &city.scene, &panorama, all),
        ("random", &random, &close, SplatSettings { channels: geometric, ..all }),
        ("opaque stack", &opaque, &close, SplatSettings { channels: geometric, ..all }),
        ("faint stack", &faint, &close, SplatSettings { channels: geometric, ..all }),
    ] {
        let gpu_scene = GpuScene::upload(&d, scene).unwrap();
        for tile in TILE_SIZES {
            let settings = SplatSettings { tile, ..base };
            let work = blend_work(scene, cam, tile, settings.tile_bounds);
            assert!(work.longest_walk > 4 * u64::from(CHUNK), "{name} tile {tile}: walks of {work:?} split little");
            let cpu = render_cpu(scene, cam, &settings);
            splatter.set_chunk_length(0).unwrap();
            let (whole, stats) = splatter.render(&gpu_scene, cam, &settings).unwrap();
            assert_eq!(stats.chunks, 0, "{name} tile {tile}: chunk length 0 splits nothing");
            let whole = whole.read(&d).unwrap();
            splatter.set_chunk_length(CHUNK).unwrap();
            let layouts = [(1, false, false), (default_blend_pixels(d.info()), true, false), (8, true, true)];
            for (pixels, window, two) in layouts {
                splatter.set_blend_pixels(pixels).unwrap();
                splatter.set_window_fetch(window);
                splatter.set_two_splats_per_step(two);
                let label = format!("{name} tile {tile}, {pixels} pixels, window fetch {window}, two splats {two}");
                let (split, stats) = splatter.render(&gpu_scene, cam, &settings).unwrap();
                // At least the chunks of the longest walk's list.
                assert!(stats.chunks >= work.longest_walk / u64::from(CHUNK), "{label}: {} chunks", stats.chunks);
                let split = split.read(&d).unwrap();
                compare(&split, &cpu, &label);
                assert_close_to(&split, &whole, 1e-5, &label);
                checked += 1;
            }
        }
    }
    assert_eq!(checked, 8 * TILE_SIZES.len() * 3);
    let text = splatter.set_chunk_length(MAX_CHUNK_LENGTH + 1).err().map(|e| e.to_string()).unwrap_or_default();
    assert!(text.contains("chunk length 1073741825: exceeds"), "{text:?}");
    splatter.set_blend_pixels(default_blend_pixels(d.info())).unwrap();
    assert_no_validation_messages(&d);
}

/// The frame's prefix sums in tiles (the GPUs' default) or runs (CPU
/// devices') give the same bits: both are exact. Switched after frames have
/// reserved their scratch, then a larger frame, so the switch keeps and grows it.
#[test]
fn scans_in_tiles_or_runs_give_the_same_frame() {
    let d = device();
    let mut splatter = Splatter::new(&d).unwrap();
    let city = demo_city(&DemoOptions { seed: 7, gaussians: 30_000, sh_degree: 1 }).unwrap();
    let scene = GpuScene::upload(&d, &city.scene).unwrap();
    let settings = all_settings();
    let default = splatter.scan_tiles();
    for (w, h) in [(203, 77), (640, 416)] {
        let cam = city.cameras[1].resized(w, h);
        splatter.set_scan_tiles(default).unwrap();
        let (first, stats) = splatter.render(&scene, &cam, &settings).unwrap();
        assert!(stats.pairs > 10_000, "{w}x{h}: {} pairs", stats.pairs);
        splatter.set_scan_tiles(!default).unwrap();
        assert_eq!(splatter.scan_tiles(), !default);
        let (other, other_stats) = splatter.render(&scene, &cam, &settings).unwrap();
        assert_eq!(other_stats.pairs, stats.pairs, "{w}x{h}");
        assert!(gbuffer_bits(&first.read(&d).unwrap()) == gbuffer_bits(&other.read(&d).unwrap()), "{w}x{h}");
    }
    assert_no_validation_messages(&d);
}

/// A scene written in another order (`srug convert --order morton`, or shuffled as a trained
/// scene's file is) renders the same frame: every channel within the twin comparison's
/// tolerances (splats whose depth keys tie blend in scene order, which the order changes), and
/// the top Gaussian the same one once its index is mapped back.
#[test]
fn the_gaussians_order_changes_no_frame() {
    let d = device();
    let mut splatter = Splatter::new(&d).unwrap();
    let city = demo_city(&DemoOptions { seed: 7, gaussians: 30_000, sh_degree: 1 }).unwrap();
    let cam = city.cameras[1].resized(203, 77);
    let settings = all_settings();
    let mut render = |scene: &Scene| {
        let gpu = GpuScene::upload(&d, scene).unwrap();
        let (g, stats) = splatter.render(&gpu, &cam, &settings).unwrap();
        (g.read(&d).unwrap(), stats.pairs)
    };
    let (base, pairs) = render(&city.scene);
    assert!(pairs > 10_000, "{pairs} pairs");
    let mut shuffled: Vec<usize> = (0..city.scene.len()).collect();
    shuffled.reverse();
    shuffled.rotate_left(12_345);
    for (name, order) in [("morton", city.scene.morton_order()), ("reversed and rotated", shuffled)] {
        let (mut other, other_pairs) = render(&city.scene.permuted(&order));
        assert_eq!(other_pairs, pairs, "{name}");
        let before = other.top_gaussian.clone();
        for t in other.top_gaussian.iter_mut().flatten().filter(|t| **t != u32::MAX) {
            *t = order[*t as usize] as u32;
        }
        assert_ne!(before, other.top_gaussian, "{name}: the order moved the top Gaussians' indices");
        let (tops, base_tops) = (other.top_gaussian.clone().unwrap(), base.top_gaussian.clone().unwrap());
        let moved = tops.iter().zip(&base_tops).filter(|(a, b)| a != b).count();
        assert!(moved * 1000 <= tops.len(), "{name}: {moved} of {} top Gaussians differ", tops.len());
        compare_with(&other, &base, name, true);
    }
    assert_no_validation_messages(&d);
}

/// A scene listed in a scrambled order and arranged on the device (GpuScene::arrange) renders
/// the frame of its file order (every channel within the twin comparison's tolerances), names
/// each pixel's top Gaussian by its file row, and gives each Gaussian its own gradients.
#[test]
fn an_arranged_scene_renders_as_listed_and_names_its_gaussians_in_file_order() {
    let d = device();
    let mut splatter = Splatter::new(&d).unwrap();
    let city = demo_city(&DemoOptions { seed: 7, gaussians: 30_000, sh_degree: 1 }).unwrap();
    let n = city.scene.len();
    let scrambled = city.scene.permuted(&(0..n).map(|i| (i * 7919 + 13) % n).collect::<Vec<_>>());
    let cam = city.cameras[1].resized(203, 77);
    let settings = all_settings();
    assert!(settings.channels.top_gaussian && settings.rgb);
    let file = GpuScene::upload(&d, &scrambled).unwrap();
    let mut arranged = GpuScene::upload(&d, &scrambled).unwrap();
    assert!(arranged.arrange(&d, SceneOrder::Auto).unwrap());
    let pixels = 203 * 77;
    let mut rng = Pcg64Mcg::seed_from_u64(5);
    let d_rgb: Vec<f32> = (0..3 * pixels).map(|_| rng.random_range(-1.0..1.0)).collect();
    let d_alpha: Vec<f32> = (0..pixels).map(|_| rng.random_range(-1.0..1.0)).collect();
    let grads = BlendGrads {
        rgb: Some(d.upload("d rgb", &d_rgb).unwrap()),
        alpha: Some(d.upload("d alpha", &d_alpha).unwrap()),
        ..BlendGrads::default()
    };
    let mut run = |scene: &GpuScene| {
        let frame = splatter.render_frame(scene, &cam, &settings).unwrap();
        let g = splatter.backward(&frame, scene, &grads, true).unwrap().read(&d).unwrap();
        (frame.gbuffer.read(&d).unwrap(), g)
    };
    let (base, base_grads) = run(&file);
    let (other, other_grads) = run(&arranged);
    compare_with(&other, &base, "arranged", true);
    let (tops, base_tops) = (other.top_gaussian.clone().unwrap(), base.top_gaussian.clone().unwrap());
    assert!(base_tops.iter().filter(|t| **t != u32::MAX).count() > pixels / 2, "most pixels see a Gaussian");
    let moved = tops.iter().zip(&base_tops).filter(|(a, b)| a != b).count();
    assert!(moved * 1000 <= tops.len(), "{moved} of {} top Gaussians differ", tops.len());
    // Gradients: each Gaussian's within 0.5% of the largest of its kind but for one in a thousand
    // (splats whose depth keys tie blend in scene order; in the wrong order nearly all would differ).
    let flat = |v: &[f32]| v.to_vec();
    let kinds: [(&str, Vec<f32>, Vec<f32>); 4] = [
        ("means", base_grads.means.concat(), other_grads.means.concat()),
        ("opacity logits", flat(&base_grads.opacity_logits), flat(&other_grads.opacity_logits)),
        ("rotations", base_grads.rotations.concat(), other_grads.rotations.concat()),
        ("values", base_grads.values.clone().unwrap().concat(), other_grads.values.clone().unwrap().concat()),
    ];
    for (name, a, b) in kinds {
        assert_eq!(a.len(), b.len(), "{name}");
        let scale = a.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        assert!(scale > 0.0, "{name}: some gradient");
        let worst = a.iter().zip(&b).map(|(x, y)| (x - y).abs()).fold(0.0f32, f32::max);
        let far = a.iter().zip(&b).filter(|(x, y)| (*x - *y).abs() > 5e-3 * scale).count();
        assert!(far * 1000 <= a.len(), "{name}: {far} of {} differ, worst {worst} against {scale}", a.len());
    }
    assert_no_validation_messages(&d);
}

#[test]
fn texel_preprocess_reads_give_the_bits_of_address_reads_at_every_sh_degree() {
    // The texel preprocess fetches means and log-scales as RGB32F, rotations
    // and (degrees 1 and 3) SH coefficients as RGBA32F where the device views
    // them so, and the keys kernel the splat records as RGBA32UI and their
    // offsets as R32UI; the same values as the address path's loads, so the same bits.
    let d = device();
    let info = d.info();
    for f in [TexelFormat::R32Float, TexelFormat::Rgb32Float, TexelFormat::Rgba32Float, TexelFormat::Rgba32Uint] {
        assert!(info.texel_formats.contains(&f), "lavapipe views {f:?} buffers");
    }
    let mut splatter = Splatter::new(&d).unwrap();
    let cam = Camera::look_at(Vec3::new(0.0, -6.0, 0.5), Vec3::ZERO, Vec3::Z, 70.0, 120, 80).unwrap();
    let geometric = Channels { depth: true, median_depth: true, normal: true, ..Channels::default() };
    let settings = SplatSettings { channels: geometric, ..all_settings() };
    for degree in 0..=3 {
        let scene = GpuScene::upload(&d, &random_scene(3000, degree, 40 + u64::from(degree), 2.0)).unwrap();
        let mut bits = Vec::new();
        for texel in [true, false] {
            splatter.set_texel_preprocess(texel).unwrap();
            bits.push(gbuffer_bits(&splatter.render(&scene, &cam, &settings).unwrap().0.read(&d).unwrap()));
        }
        let differ = bits[0].iter().zip(&bits[1]).filter(|(a, b)| a != b).count();
        assert_eq!(differ, 0, "SH degree {degree}: {differ} values differ");
    }
    assert_no_validation_messages(&d);
}

#[test]
fn a_batch_of_cameras_renders_the_same_bits_as_one_camera_at_a_time() {
    // render_frames records many cameras per submission (preprocess and scan
    // of all, one read of their pair counts, then every sort and blend); each
    // frame must be exactly the frame render_frame gives for its camera alone,
    // across more cameras than one submission takes, sizes mixed.
    let d = device();
    let mut splatter = Splatter::new(&d).unwrap();
    let city = demo_city(&DemoOptions { seed: 7, gaussians: 20_000, sh_degree: 1 }).unwrap();
    let gpu_scene = GpuScene::upload(&d, &city.scene).unwrap();
    let count = FRAMES_PER_SUBMISSION + 3;
    let cameras: Vec<Camera> = (0..count)
        .map(|i| {
            let base = &city.cameras[i % city.cameras.len()];
            let size = if i % 2 == 0 { (88, 24) } else { (61, 37) };
            let mut cam = base.resized(size.0, size.1);
            cam.position += Vec3::new(0.4 * i as f32, 0.0, 0.0);
            cam
        })
        .collect();
    let settings = all_settings();
    // Also with the split blend's chunks short (its scratch is shared by the batch's views).
    for chunk_length in [splatter.chunk_length(), 16] {
        splatter.set_chunk_length(chunk_length).unwrap();
        let batch = splatter.render_frames(&gpu_scene, &cameras, &settings).unwrap();
        assert_eq!(batch.len(), count);
        for (i, (frame, cam)) in batch.iter().zip(&cameras).enumerate() {
            let label = format!("camera {i}, chunk length {chunk_length}");
            let alone = splatter.render_frame(&gpu_scene, cam, &settings).unwrap();
            assert_eq!((frame.gbuffer.width, frame.gbuffer.height), (cam.width, cam.height), "{label}");
            assert_eq!(frame.stats.pairs, alone.stats.pairs, "{label}: pairs");
            assert!(frame.stats.pairs > 0, "{label} sees the street");
            assert_eq!(frame.stats.chunks, alone.stats.chunks, "{label}: chunks");
            assert!(chunk_length != 16 || frame.stats.chunks > 0, "{label}: no list split");
            let (a, b) =
                (gbuffer_bits(&frame.gbuffer.read(&d).unwrap()), gbuffer_bits(&alone.gbuffer.read(&d).unwrap()));
            assert!(a == b, "{label}: the batched frame differs from the one rendered alone");
            let stages: Vec<&str> = frame.stats.timings.stages.iter().map(|s| s.name.as_str()).collect();
            for stage in ["preprocess", "scan", "keys", "sort", "ranges", "blend"] {
                assert_eq!(stages.iter().filter(|s| **s == stage).count(), 1, "{label}: {stage} in {stages:?}");
            }
        }
    }
    // Batch sizes from the memory budget: a street frame of 200k Gaussians at
    // 704x192 (rgb: 100 bytes per Gaussian, 16 per pixel; every channel: 148 and
    // 64, with packed features 124), never fewer than one camera however large, never more than
    // a submission takes.
    let street = city.cameras[0].resized(704, 192);
    let all = SplatSettings { channels: Channels::ALL, ..SplatSettings::default() };
    assert_eq!(cameras_per_batch(200_000, &street, &SplatSettings::default(), BATCH_BYTES), 12);
    assert_eq!(cameras_per_batch(200_000, &street, &all, BATCH_BYTES), 7);
    let packed = SplatSettings { packed_features: true, ..all };
    assert_eq!(cameras_per_batch(200_000, &street, &packed, BATCH_BYTES), 8);
    assert_eq!(cameras_per_batch(u64::MAX, &street, &all, BATCH_BYTES), 1);
    assert_eq!(cameras_per_batch(10, &street.resized(8, 8), &all, BATCH_BYTES), FRAMES_PER_SUBMISSION);
    // Nothing to render is no work; one bad camera fails the whole call.
    assert!(splatter.render_frames(&gpu_scene, &[], &settings).unwrap().is_empty());
    let mut bad = cameras[..3].to_vec();
    bad[1] = bad[1].resized(70_000, 70_000);
    let text = splatter.render_frames(&gpu_scene, &bad, &settings).err().map(|e| e.to_string()).unwrap_or_default();
    assert!(text.contains("image 70000x70000") && text.contains("too large"), "{text}");
    // Few pixels but 2^22 tile columns (the kernels count tiles in floats, exact below 2^23).
    bad[1] = cameras[1].resized(16 << 22, 1);
    let text = splatter.render_frames(&gpu_scene, &bad, &settings).err().map(|e| e.to_string()).unwrap_or_default();
    assert!(text.contains("image 67108864x1") && text.contains("too large"), "{text}");
    assert_no_validation_messages(&d);
}

#[test]
fn depth_keys_order_depths_to_sixteen_mantissa_bits() {
    let cam = Camera::look_at(Vec3::ZERO, Vec3::Y, Vec3::Z, 60.0, 64, 48).unwrap();
    let key = DepthKey::of(&cam);
    assert_eq!((key.bits, key.shift), (21, 7), "the default planes, 0.01 to 10⁴");
    // Monotone in depth and within its bits from the near plane to the far one.
    let (mut depth, mut last) = (cam.near, 0u32);
    while depth < cam.far {
        let k = key.key(depth);
        assert!(k >= last && k < 1 << key.bits, "depth {depth}: key {k} after {last}");
        (depth, last) = (depth * 1.0007, k);
    }
    // Depths 2⁻¹⁵ apart (relative) get different keys; 2⁻¹⁹ apart, often the same.
    for d in [0.02f32, 0.7, 13.0, 420.0, 9000.0] {
        assert!(key.key(d * (1.0 + 2f32.powi(-15))) > key.key(d), "{d}");
    }
    let ties = (0..1000).filter(|i| {
        let d = 1.0 + *i as f32 * 0.0137;
        key.key(d) == key.key(d * (1.0 + 2f32.powi(-19)))
    });
    assert!(ties.count() > 500);
    // Planes that are not 0 < near < far < ∞: the float's bits whole.
    let open = DepthKey::of(&Camera { far: f32::INFINITY, ..cam.clone() });
    assert_eq!((open.bits, open.shift, open.key(3.5)), (32, 0, 3.5f32.to_bits()));
}

/// Two overlapping discs nearer each other than the depth key resolves keep
/// their scene order on the GPU and in the twin: the first one listed is in
/// front, whichever is nearer.
#[test]
fn splats_the_depth_key_cannot_tell_apart_blend_in_scene_order() {
    let d = device();
    let mut splatter = Splatter::new(&d).unwrap();
    let cam = Camera::look_at(Vec3::ZERO, Vec3::Y, Vec3::Z, 60.0, 32, 32).unwrap();
    let settings = SplatSettings { channels: Channels::default(), ..all_settings() };
    // 64 float steps apart in the middle of one key's 128.
    let base = cam.near.to_bits() + ((5.0f32.to_bits() - cam.near.to_bits()) & !127);
    let (near, far) = (f32::from_bits(base + 32), f32::from_bits(base + 96));
    assert_eq!(DepthKey::of(&cam).key(near), DepthKey::of(&cam).key(far));
    let disc = |y: f32, red: bool| {
        let mut g = one_gaussian([0.0, y, 0.0], -1.0, 8.0);
        g.sh = if red { vec![2.0, -2.0, -2.0] } else { vec![-2.0, -2.0, 2.0] };
        g
    };
    // Listed first at the farther depth: red, then blue.
    for red_first in [true, false] {
        let (mut scene, second) = (disc(far, red_first), disc(near, !red_first));
        scene.means.extend(second.means);
        scene.sh.extend(second.sh);
        scene.opacity_logits.extend(second.opacity_logits);
        scene.log_scales.extend(second.log_scales);
        scene.rotations.extend(second.rotations);
        let g = render_both(&d, &mut splatter, &scene, &cam, &settings, "tied discs");
        let rgb = g.rgb_values().unwrap();
        let centre = &rgb[(16 * 32 + 16) * 3..][..3];
        assert_eq!(centre[0] > centre[2], red_first, "centre {centre:?}");
    }
    assert_no_validation_messages(&d);
}

/// Gaussians centred outside the image whose tails reach into it: the
/// preprocess's early cull (a bound on the radius from the largest scale)
/// keeps every one the full projection keeps, on pinhole and orthographic cameras.
#[test]
fn splats_centred_off_the_image_that_reach_in_are_kept() {
    let d = device();
    let mut splatter = Splatter::new(&d).unwrap();
    let settings = SplatSettings {
        channels: Channels { depth: true, median_depth: true, ..Channels::default() },
        ..all_settings()
    };
    let pinhole = Camera::look_at(Vec3::new(0.0, -6.0, 0.0), Vec3::ZERO, Vec3::Z, 50.0, 96, 64).unwrap();
    let ortho = Camera::orthographic(Vec3::new(0.0, -6.0, 0.0), Vec3::Y, Vec3::Z, 4.0, 3.0, 96, 64, 0.0, 50.0).unwrap();
    let mut rng = Pcg64Mcg::seed_from_u64(21);
    for (label, cam) in [("pinhole", pinhole), ("orthographic", ortho)] {
        let mut scene = random_scene(4000, 1, 77, 12.0);
        for (i, s) in scene.log_scales.iter_mut().enumerate() {
            // Flat and elongated up to 2 m, so the largest scale bounds a long tail.
            *s = [rng.random_range(-4.0..0.7), rng.random_range(-4.0..0.7), if i % 2 == 0 { -5.0 } else { -1.0 }];
        }
        // Only those whose centre projects outside the image.
        let (w, h) = (f64::from(cam.width), f64::from(cam.height));
        let outside: Vec<bool> = (0..scene.len())
            .map(|i| {
                preprocess_one(&scene, i, &cam, NormalSource::Stored, DEFAULT_TILE)
                    .is_some_and(|s| s.mean.x < 0.0 || s.mean.y < 0.0 || s.mean.x >= w || s.mean.y >= h)
            })
            .collect();
        let scene = scene.select(&outside);
        let g = render_both(&d, &mut splatter, &scene, &cam, &settings, label);
        let reached = g.alpha.iter().filter(|a| **a > 0.05).count();
        assert!(scene.len() > 200 && reached > 100, "{label}: {} splats, {reached} pixels reached", scene.len());
    }
    assert_no_validation_messages(&d);
}

#[test]
fn random_scenes_match_cpu_twin() {
    let d = device();
    let mut splatter = Splatter::new(&d).unwrap();
    let settings = SplatSettings {
        channels: Channels { depth: true, median_depth: true, normal: true, ..Channels::default() },
        ..all_settings()
    };
    for (n, degree, w, h) in [(1usize, 0u32, 64u32, 48u32), (500, 1, 100, 70), (4000, 3, 160, 90)] {
        let scene = random_scene(n, degree, n as u64, 2.0);
        let cam = Camera::look_at(Vec3::new(0.0, -6.0, 0.5), Vec3::ZERO, Vec3::Z, 70.0, w, h).unwrap();
        render_both(&d, &mut splatter, &scene, &cam, &settings, &format!("random_{n}"));
        // Near and far planes tight around the scene: the depth key keeps only the bits
        // between them, to 16 mantissa bits (16 here, 21 at the default planes, not the
        // float's 32), and splats beyond them are culled.
        assert_eq!(srug::splat::depth_key_bits(&cam), 21, "the default planes, 0.01 to 10⁴");
        let tight = Camera { near: 4.5, far: 7.5, ..cam };
        assert_eq!(srug::splat::depth_key_bits(&tight), 16);
        render_both(&d, &mut splatter, &scene, &tight, &settings, &format!("random_{n}_tight_planes"));
    }
    assert_no_validation_messages(&d);
}

#[test]
fn demo_city_matches_cpu_twin_in_every_channel() {
    let d = device();
    let mut splatter = Splatter::new(&d).unwrap();
    let city = demo_city(&DemoOptions { seed: 7, gaussians: 60_000, sh_degree: 2 }).unwrap();
    let cam = city.cameras[1].resized(352, 96);
    let variants = blend_variants(&d);
    // The subgroup-load blend both with texel-buffer reads (the default, at every
    // pixels per invocation) and by device address (with the preprocess reading
    // the scene by device address too).
    let runs = variants.iter().flat_map(|&v| {
        let texel = if v == BlendVariant::SubgroupLoads {
            BLEND_PIXELS.iter().map(|&p| (true, p)).chain([(false, 1)]).collect()
        } else {
            vec![(true, default_blend_pixels(d.info()))]
        };
        texel.into_iter().map(move |(t, p)| (v, t, p))
    });
    for (variant, texel, pixels) in runs {
        splatter.set_blend_variant(variant).unwrap();
        splatter.set_texel_blend(texel).unwrap();
        splatter.set_texel_preprocess(texel).unwrap();
        splatter.set_blend_pixels(pixels).unwrap();
        let label = format!("demo_{variant:?}_texel_{texel}_pixels_{pixels}");
        let g = render_both(&d, &mut splatter, &city.scene, &cam, &all_settings(), &label);
        let covered = g.alpha.iter().filter(|a| **a > 0.5).count();
        assert!(covered * 10 > g.alpha.len() * 9, "the street should cover the view: {covered} of {}", g.alpha.len());
    }
    assert_no_validation_messages(&d);
}

#[test]
fn real_trained_scene_matches_cpu_twin() {
    let Some(data) = srug_tests::shared_data() else {
        eprintln!("skipped: ../shared/data is absent");
        return;
    };
    let d = device();
    let mut splatter = Splatter::new(&d).unwrap();
    let scene = read_ply(data.join("scenes").join("trained_iter7000.ply")).unwrap();
    // Look from the median centre toward the densest side (the file ships no cameras).
    let mut xs: Vec<Vec3> = scene.means.iter().map(|m| Vec3::from_array(*m)).collect();
    xs.sort_by(|a, b| a.x.total_cmp(&b.x));
    let centre = xs[xs.len() / 2];
    let settings = SplatSettings {
        channels: Channels { depth: true, median_depth: true, normal: true, ..Channels::default() },
        ..all_settings()
    };
    let mut covered = 0;
    for dir in [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y] {
        let cam = Camera::look_at(centre - dir * 50.0, centre, Vec3::Z, 60.0, 240, 136).unwrap();
        let g = render_both(&d, &mut splatter, &scene, &cam, &settings, &format!("trained_{dir}"));
        covered += g.alpha.iter().filter(|a| **a > 0.1).count();
    }
    assert!(covered > 1000, "the trained scene should be visible from somewhere: {covered} pixels");
    assert_no_validation_messages(&d);
}

fn one_gaussian(mean: [f32; 3], log_scale: f32, opacity_logit: f32) -> Scene {
    Scene {
        means: vec![mean],
        sh_degree: 0,
        sh: vec![0.5, 0.2, -0.3],
        opacity_logits: vec![opacity_logit],
        log_scales: vec![[log_scale; 3]],
        rotations: vec![[1.0, 0.0, 0.0, 0.0]],
        ..Scene::default()
    }
}

#[test]
fn extremes_give_finite_outputs() {
    let d = device();
    let mut splatter = Splatter::new(&d).unwrap();
    let settings = SplatSettings {
        channels: Channels { depth: true, median_depth: true, normal: true, ..Channels::default() },
        ..all_settings()
    };
    let cam = Camera::look_at(Vec3::ZERO, Vec3::Y, Vec3::Z, 60.0, 64, 48).unwrap();
    let near = cam.near;
    let cases: Vec<(&str, Scene)> = vec![
        ("behind the camera", one_gaussian([0.0, -3.0, 0.0], -1.0, 2.0)),
        ("at the camera", one_gaussian([0.0, 0.0, 0.0], -1.0, 2.0)),
        ("at the near plane", one_gaussian([0.0, near, 0.0], -1.0, 2.0)),
        ("just past the near plane", one_gaussian([0.0, near * 1.01, 0.0], -5.0, 2.0)),
        ("scale 1e-8", one_gaussian([0.0, 3.0, 0.0], (1e-8f32).ln(), 2.0)),
        ("scale 1e4", one_gaussian([0.0, 3.0, 0.0], (1e4f32).ln(), 2.0)),
        ("opacity 0", one_gaussian([0.0, 3.0, 0.0], -1.0, -100.0)),
        ("opacity 1", one_gaussian([0.0, 3.0, 0.0], -1.0, 100.0)),
        ("camera inside", one_gaussian([0.0, 0.5, 0.0], 1.0, 2.0)),
        ("far beyond", one_gaussian([0.0, 1e6, 0.0], -1.0, 2.0)),
        ("nothing", Scene { sh_degree: 0, ..Scene::default() }),
    ];
    for variant in [BlendVariant::SharedBatches, splatter.blend_variant()] {
        splatter.set_blend_variant(variant).unwrap();
        for (label, scene) in &cases {
            scene.validate(label).unwrap();
            render_both(&d, &mut splatter, scene, &cam, &settings, &format!("{label} ({variant:?})"));
        }
    }
    // 1×1 and 16384-wide images.
    let scene = random_scene(300, 1, 9, 2.0);
    for (w, h) in [(1u32, 1u32), (16_384, 8)] {
        let cam = Camera::look_at(Vec3::new(0.0, -6.0, 0.0), Vec3::ZERO, Vec3::Z, 90.0, w, h).unwrap();
        render_both(&d, &mut splatter, &scene, &cam, &settings, &format!("{w}x{h}"));
    }
    // 66,049 tiles of 8 pixels: more workgroups than a grid row holds, so the per-tile
    // kernels run on a 2D grid with a spare workgroup, which must leave without a tile. At 4.2M
    // pixels a few land on the α = 1/255 cutoff, where f32 and f64 can take a splat more or less.
    let cam = Camera::look_at(Vec3::new(0.0, -6.0, 0.0), Vec3::ZERO, Vec3::Z, 90.0, 2056, 2056).unwrap();
    let rgb_only = SplatSettings { channels: Channels::default(), tile: 8, ..all_settings() };
    let (out, _) = splatter.render(&GpuScene::upload(&d, &scene).unwrap(), &cam, &rgb_only).unwrap();
    compare_with(&out.read(&d).unwrap(), &render_cpu(&scene, &cam, &rgb_only), "2056x2056 at 8-pixel tiles", true);
    assert_no_validation_messages(&d);
}

#[test]
fn orthographic_camera_matches_cpu_twin() {
    let d = device();
    let mut splatter = Splatter::new(&d).unwrap();
    let scene = random_scene(2000, 2, 4, 3.0);
    let sun = Camera::orthographic(
        Vec3::new(0.0, 0.0, 20.0),
        Vec3::new(0.3, 0.1, -1.0),
        Vec3::Y,
        10.0,
        8.0,
        128,
        96,
        0.0,
        50.0,
    )
    .unwrap();
    let settings = SplatSettings {
        channels: Channels { depth: true, median_depth: true, ..Channels::default() },
        ..all_settings()
    };
    let g = render_both(&d, &mut splatter, &scene, &sun, &settings, "orthographic");
    assert!(g.alpha.iter().any(|a| *a > 0.5));
    assert_no_validation_messages(&d);
}

/// A scene and its cameras far from the world's origin (a city in kilometres
/// from a survey's origin) render as near it, against the twin: the shaders
/// take a point to the camera as rotation · (point − position), so no
/// coordinate of 1e5 m enters a sum that cancels. With rotation · point +
/// translation instead, f32 loses centimetres there: the pinhole view's alpha
/// was 7.4e-3 off the twin (tolerance 2e-3) before the change.
#[test]
fn far_from_the_origin_matches_cpu_twin() {
    let d = device();
    let mut splatter = Splatter::new(&d).unwrap();
    let city = demo_city(&DemoOptions { seed: 7, gaussians: 20_000, sh_degree: 1 }).unwrap();
    let offset = Vec3::new(1.0e5, -7.0e4, 30.0);
    let mut scene = city.scene.clone();
    move_scene(&mut scene, offset);
    let street = city.cameras[1].resized(352, 96);
    let street = Camera { position: street.position + offset, ..street };
    let above = Camera::orthographic(
        street.position + Vec3::new(0.0, 0.0, 60.0),
        Vec3::new(0.3, 0.1, -1.0),
        Vec3::Y,
        80.0,
        40.0,
        160,
        80,
        0.0,
        200.0,
    )
    .unwrap();
    let settings = SplatSettings {
        channels: Channels { depth: true, median_depth: true, normal: true, ..Channels::default() },
        ..all_settings()
    };
    for (camera, label) in [(&street, "far_pinhole"), (&above, "far_orthographic")] {
        let g = render_both(&d, &mut splatter, &scene, camera, &settings, label);
        let covered = g.alpha.iter().filter(|a| **a > 0.5).count();
        assert!(covered * 2 > g.alpha.len(), "{label}: the city should fill most of the view: {covered} pixels");
    }
    assert_no_validation_messages(&d);
}

#[test]
fn requested_channels_only_and_missing_attributes_refused() {
    let d = device();
    let mut splatter = Splatter::new(&d).unwrap();
    let scene = random_scene(100, 0, 5, 2.0);
    let gpu_scene = GpuScene::upload(&d, &scene).unwrap();
    let cam = Camera::look_at(Vec3::new(0.0, -6.0, 0.0), Vec3::ZERO, Vec3::Z, 70.0, 32, 32).unwrap();
    let (out, _) = splatter.render(&gpu_scene, &cam, &SplatSettings::default()).unwrap();
    assert!(
        out.get(Channel::Depth).is_none() && out.get(Channel::Normal).is_none() && out.get(Channel::Albedo).is_none(),
        "unrequested channels were allocated"
    );
    assert_eq!(out.bytes(), 4 * 32 * 32 * 4);
    let settings =
        SplatSettings { channels: Channels { albedo: true, ..Channels::default() }, ..SplatSettings::default() };
    match splatter.render(&gpu_scene, &cam, &settings) {
        Err(srug::Error::InvalidArgument { what, why }) => {
            assert!(what.contains("albedo") && why.contains("scene has no albedo"), "{what}: {why}")
        }
        other => panic!("expected a refusal, got {:?}", other.map(|_| ())),
    }
    assert!(
        Channels::parse("rgb,depth,normal").unwrap() == Channels { depth: true, normal: true, ..Channels::default() }
    );
    assert!(Channels::parse("rgb,bogus").is_err());
    assert_no_validation_messages(&d);
}

#[test]
fn rgb_off_drops_only_colour_in_every_variant() {
    let d = device();
    let mut splatter = Splatter::new(&d).unwrap();
    let city = demo_city(&DemoOptions { seed: 3, gaussians: 20_000, sh_degree: 2 }).unwrap();
    let cam = city.cameras[0].resized(133, 71);
    let gpu_scene = GpuScene::upload(&d, &city.scene).unwrap();
    let variants = blend_variants(&d);
    let on = all_settings();
    let off = SplatSettings { rgb: false, ..on };
    for variant in variants {
        splatter.set_blend_variant(variant).unwrap();
        let (with, _) = splatter.render(&gpu_scene, &cam, &on).unwrap();
        let (without, _) = splatter.render(&gpu_scene, &cam, &off).unwrap();
        assert!(without.rgb.is_none(), "{variant:?}: rgb allocated although not asked for");
        assert_eq!(with.bytes() - without.bytes(), 3 * 4 * 133 * 71, "{variant:?}: only the rgb buffer is saved");
        let (with, without) = (with.read(&d).unwrap(), without.read(&d).unwrap());
        assert!(without.rgb_values().unwrap_err().to_string().contains("no rgb channel"));
        // The colour is the only thing that changes: every other channel bit for bit.
        let rest = |g: &GBuffer| -> Vec<(&'static str, Vec<u32>)> {
            g.channels()
                .into_iter()
                .filter(|c| c.0 != "rgb")
                .map(|(n, v, _)| (n, v.iter().map(|x| x.to_bits()).collect()))
                .collect()
        };
        assert_eq!(rest(&with).len(), 9, "alpha and the eight optional channels");
        assert!(rest(&with) == rest(&without), "{variant:?}: a channel other than rgb changed");
        // And the twin, without rgb as well.
        render_both(&d, &mut splatter, &city.scene, &cam, &off, &format!("rgb_off_{variant:?}"));
    }
    assert!(render_cpu(&city.scene, &cam, &off).rgb.is_none(), "the twin skips rgb too");
    assert_no_validation_messages(&d);
}

/// Without rgb the preprocess evaluates no colour, so no SH coefficient reaches
/// anything: every listed record's colour is 0 (where rgb gives colour), and a
/// scene whose SH are all NaN renders the same bits in every channel as the
/// scene itself, on both preprocess paths (the records pre-filled with NaN).
#[test]
fn rgb_off_reads_no_sh_coefficient() {
    let d = device();
    let mut splatter = Splatter::new(&d).unwrap();
    let city = demo_city(&DemoOptions { seed: 5, gaussians: 20_000, sh_degree: 3 }).unwrap();
    let cam = city.cameras[0].resized(176, 48);
    let mut poisoned = city.scene.clone();
    poisoned.sh.iter_mut().for_each(|c| *c = f32::NAN);
    let scene = GpuScene::upload(&d, &city.scene).unwrap();
    let poisoned = GpuScene::upload(&d, &poisoned).unwrap();
    let on = all_settings();
    let off = SplatSettings { rgb: false, ..on };
    for texel in [true, false] {
        splatter.set_texel_preprocess(texel).unwrap();
        // Each listed record's colour (a record is 16 floats: head, conic, colour, rect).
        let mut colours = |scene: &GpuScene, settings: &SplatSettings| -> (Vec<[f32; 3]>, Vec<u32>) {
            let frame = splatter.render_frame(scene, &cam, settings).unwrap();
            let offsets: Vec<u32> = d.read_buffer(&frame.pair_offsets).unwrap();
            let splats: Vec<f32> = d.read_buffer(&frame.splats).unwrap();
            let listed = (0..city.scene.len()).filter(|&i| offsets[i + 1] > offsets[i]);
            let colours = listed.map(|i| [splats[16 * i + 8], splats[16 * i + 9], splats[16 * i + 10]]).collect();
            (colours, gbuffer_bits(&frame.gbuffer.read(&d).unwrap()))
        };
        let (with, _) = colours(&scene, &on);
        let (without, bits) = colours(&scene, &off);
        let (_, poisoned_bits) = colours(&poisoned, &off);
        assert!(without.len() > 1_000 && without.len() == with.len(), "texel {texel}: {} listed", without.len());
        assert!(with.iter().any(|c| c.iter().any(|&v| v > 0.0)), "texel {texel}: rgb gives colour");
        assert!(without.iter().all(|c| *c == [0.0; 3]), "texel {texel}: a colour without rgb");
        assert!(bits == poisoned_bits, "texel {texel}: the SH changed a channel without rgb");
    }
    assert_no_validation_messages(&d);
}

/// The preprocess reads only the attributes of the feature channels a frame
/// blends: with albedo alone, every listed record's albedo is the all-channel
/// frame's bit for bit and its roughness, metallic, ao and visibility are 0,
/// where the all-channel frame's are not (records unpacked: 12 floats each).
#[test]
fn only_blended_feature_channels_read_their_attributes() {
    let d = device();
    let mut splatter = Splatter::new(&d).unwrap();
    let city = demo_city(&DemoOptions { seed: 5, gaussians: 20_000, sh_degree: 1 }).unwrap();
    let cam = city.cameras[0].resized(176, 48);
    let scene = GpuScene::upload(&d, &city.scene).unwrap();
    let all = all_settings();
    let albedo_only = SplatSettings { channels: Channels { albedo: true, ..Channels::default() }, ..all };
    let mut features = |settings: &SplatSettings| -> Vec<[u32; 12]> {
        let frame = splatter.render_frame(&scene, &cam, settings).unwrap();
        let offsets: Vec<u32> = d.read_buffer(&frame.pair_offsets).unwrap();
        let words: Vec<u32> = d.read_buffer(frame.features.as_ref().unwrap()).unwrap();
        (0..city.scene.len())
            .filter(|&i| offsets[i + 1] > offsets[i])
            .map(|i| std::array::from_fn(|k| words[12 * i + k]))
            .collect()
    };
    let (full, albedo) = (features(&all), features(&albedo_only));
    assert!(full.len() > 1_000 && full.len() == albedo.len(), "{} listed", full.len());
    // Albedo at words 4-6; roughness 3, metallic 7, ao 8, visibility 9.
    for (f, a) in full.iter().zip(&albedo) {
        assert_eq!(f[4..7], a[4..7], "albedo");
        assert!([3, 7, 8, 9].iter().all(|&k| a[k] == 0), "a material not blended was read: {a:?}");
    }
    assert!(full.iter().any(|f| [3, 7, 8, 9].iter().all(|&k| f32::from_bits(f[k]) > 0.0)), "every material read");
    assert_no_validation_messages(&d);
}

/// The top-Gaussian channel names the splat with the largest blend weight
/// wᵢ = αᵢ Tᵢ, exactly, in every blend variant: a faint splat in front of an
/// opaque one loses to it (0.3 against 0.7·α), a strong one in front wins,
/// and pixels nothing reaches hold u32::MAX.
#[test]
fn top_gaussian_is_the_largest_weight_in_every_variant() {
    let d = device();
    let mut splatter = Splatter::new(&d).unwrap();
    let faint = one_gaussian([-0.6, 0.0, 0.0], -1.2, (0.3f32 / 0.7).ln());
    let strong = one_gaussian([0.6, 0.0, 0.0], -1.2, 4.0);
    let back = one_gaussian([0.0, 2.0, 0.0], -0.2, 6.0);
    let mut scene = faint.clone();
    for s in [&strong, &back] {
        scene.means.extend(&s.means);
        scene.log_scales.extend(&s.log_scales);
        scene.rotations.extend(&s.rotations);
        scene.opacity_logits.extend(&s.opacity_logits);
        scene.sh.extend(&s.sh);
    }
    let cam = Camera::look_at(Vec3::new(0.0, -5.0, 0.0), Vec3::ZERO, Vec3::Z, 60.0, 96, 64).unwrap();
    let settings = SplatSettings { channels: Channels { top_gaussian: true, ..Channels::default() }, ..all_settings() };
    let cpu = render_cpu(&scene, &cam, &settings).top_gaussian.unwrap();
    let at = |x: f32, y: f32, z: f32| {
        let p = cam.project(cam.world_to_camera(Vec3::new(x, y, z)));
        p.y as usize * 96 + p.x as usize
    };
    assert_eq!(cpu[at(-0.6, 0.0, 0.0)], 2, "the opaque splat behind outweighs the faint one in front");
    assert_eq!(cpu[at(0.6, 0.0, 0.0)], 1, "the strong splat in front outweighs the one behind");
    assert_eq!(cpu[0], u32::MAX, "nothing reaches the corner");
    for variant in blend_variants(&d) {
        splatter.set_blend_variant(variant).unwrap();
        let gpu_scene = GpuScene::upload(&d, &scene).unwrap();
        let (out, _) = splatter.render(&gpu_scene, &cam, &settings).unwrap();
        let gpu = out.read(&d).unwrap().top_gaussian.unwrap();
        let differ = gpu.iter().zip(&cpu).filter(|(a, b)| a != b).count();
        assert_eq!(differ, 0, "{variant:?}: top Gaussian differs from the twin at {differ} pixels");
    }
    assert_no_validation_messages(&d);
}

/// Cameras with lenses: a barrel-distorted OpenCV camera (radial k1..k3,
/// tangential p1, p2), a FOV-model camera (ω = 0.9), an EUCM camera (α 0.6,
/// β 1.1), a division-model camera (k −0.2) and a thin-prism fisheye on a demo
/// street camera, a 180° fisheye looking down the street, and a 360°
/// equirectangular panorama from the same place (wrapping at its edges).
fn lens_cameras(city: &srug::scene::demo::DemoCity) -> Vec<(&'static str, Camera)> {
    use srug::camera::lens::Lens;
    let street = city.cameras[1].resized(352, 96);
    let opencv = Camera {
        lens: Lens::RadialTangential { k: [-0.25, 0.06, -0.005, 0.0, 0.0, 0.0], p: [0.001, -0.002] },
        ..street.clone()
    };
    let fov = Camera { lens: Lens::Fov { omega: 0.9 }, ..street.clone() };
    let eucm = Camera { lens: Lens::Eucm { alpha: 0.6, beta: 1.1 }, ..street.clone() };
    let division = Camera { lens: Lens::Division { k: -0.2 }, ..street.clone() };
    let prism = Camera {
        lens: Lens::ThinPrismFisheye { k: [0.01, -0.002, 0.0003, -0.00004], p: [0.001, -0.0005], s: [0.0008, -0.0006] },
        ..street.clone()
    };
    let aria = Camera {
        lens: Lens::RadTanThinPrismFisheye {
            k: [0.01, -0.002, 0.0003, -0.00004, 0.00001, -0.000002],
            p: [0.001, -0.0005],
            s: [0.0008, -0.0006, 0.0002, -0.0001],
        },
        ..street.clone()
    };
    let fisheye = Camera {
        width: 160,
        height: 160,
        projection: srug::scene::Projection::Pinhole { fx: 50.0, fy: 50.5, cx: 80.0, cy: 79.5 },
        lens: Lens::Fisheye { k: [0.01, -0.002, 0.0003, -0.00004] },
        ..street.clone()
    };
    let panorama = Camera::panorama(street.position, street.rotation, 384).unwrap();
    vec![
        ("opencv", opencv),
        ("fov", fov),
        ("eucm", eucm),
        ("division", division),
        ("thin_prism_fisheye", prism),
        ("rad_tan_thin_prism_fisheye", aria),
        ("fisheye", fisheye),
        ("equirectangular", panorama),
    ]
}

/// Splatting through lenses matches the CPU twin (the twin's lens maths are
/// checked against pycolmap and OpenCV) in every channel, in each blend variant.
#[test]
fn lens_cameras_match_cpu_twin() {
    let d = device();
    let mut splatter = Splatter::new(&d).unwrap();
    let city = demo_city(&DemoOptions { seed: 7, gaussians: 40_000, sh_degree: 1 }).unwrap();
    let gpu_scene = GpuScene::upload(&d, &city.scene).unwrap();
    for (name, cam) in lens_cameras(&city) {
        let cpu = render_cpu(&city.scene, &cam, &all_settings());
        for variant in blend_variants(&d) {
            splatter.set_blend_variant(variant).unwrap();
            let g = splatter.render(&gpu_scene, &cam, &all_settings()).unwrap().0.read(&d).unwrap();
            compare_with(&g, &cpu, &format!("lens_{name}_{variant:?}"), true);
            let covered = g.alpha.iter().filter(|a| **a > 0.5).count();
            // The panorama sees the sky above the street too.
            let share = if name == "equirectangular" { 3 } else { 2 };
            assert!(
                covered * share > g.alpha.len(),
                "{name}: the street should fill the view: {covered} of {}",
                g.alpha.len()
            );
        }
    }
    assert_no_validation_messages(&d);
}

/// A full panorama wraps: a Gaussian straight behind the camera straddles the
/// left and right edges and renders exactly as the same Gaussian straight
/// ahead, shifted by half the width (on the GPU in every blend variant and in
/// the twin), with a tile-multiple width and one whose last tile is partial;
/// its depth is the distance from the camera. Both tile bounds.
#[test]
fn panorama_wraps_at_the_seam() {
    let d = device();
    let mut splatter = Splatter::new(&d).unwrap();
    for (width, tile_bounds) in
        [(256u32, TileBounds::Ellipse), (200, TileBounds::Ellipse), (200, TileBounds::Rectangle)]
    {
        let settings = SplatSettings {
            channels: Channels { depth: true, ..Channels::default() },
            rgb: false,
            tile_bounds,
            ..all_settings()
        };
        let cam = Camera::panorama(Vec3::ZERO, glam::Mat3::IDENTITY, width).unwrap();
        assert_eq!(cam.wrap_period(), Some(width as f32));
        let render = |scene: &Scene, splatter: &mut Splatter| {
            let cpu = render_cpu(scene, &cam, &settings);
            let mut outs = Vec::new();
            for variant in blend_variants(&d) {
                splatter.set_blend_variant(variant).unwrap();
                let gpu_scene = GpuScene::upload(&d, scene).unwrap();
                let g = splatter.render(&gpu_scene, &cam, &settings).unwrap().0.read(&d).unwrap();
                compare_with(&g, &cpu, &format!("panorama_{width}_{variant:?}"), false);
                outs.push(g);
            }
            (cpu, outs)
        };
        let (behind, behind_gpu) = render(&one_gaussian([0.0, 0.0, -4.0], -1.5, 3.0), &mut splatter);
        let (ahead, _) = render(&one_gaussian([0.0, 0.0, 4.0], -1.5, 3.0), &mut splatter);
        let (w, h) = (width as usize, (width / 2) as usize);
        let at = |x: usize, y: usize| y * w + x;
        let (mut worst, mut mass) = (0.0f32, 0.0f32);
        for y in 0..h {
            for x in 0..w {
                let a = behind.alpha[at(x, y)];
                let b = ahead.alpha[at((x + w / 2) % w, y)];
                worst = worst.max((a - b).abs());
                mass += a;
            }
        }
        assert!(worst < 1e-5, "width {width}: behind vs ahead shifted by half differ by {worst}");
        assert!(mass > 20.0, "width {width}: the blob covers only {mass} pixels of alpha");
        for g in &behind_gpu {
            let (left, right) = (g.alpha[at(0, h / 2)], g.alpha[at(w - 1, h / 2)]);
            assert!(left > 0.5 && right > 0.5, "width {width}: both edges show the blob: {left} / {right}");
            let z = g.get(Channel::Depth).unwrap()[at(0, h / 2)] / left;
            assert!((z - 4.0).abs() < 1e-3, "width {width}: depth at the seam {z}, not the distance 4");
        }
    }
    assert_no_validation_messages(&d);
}

/// Small isolated Gaussians seen through each lens land where the lens model
/// (== pycolmap and cv2.projectPoints / cv2.fisheye.projectPoints, within
/// 1e-12 px) sends their centres: alpha-weighted blob centroids within
/// 0.1 px on average and 0.5 px at worst, across the whole image including
/// the corners (fisheye: up to 80° off axis).
#[test]
fn lens_blob_centroids_match_the_lens_projection() {
    use srug::camera::lens::{Intrinsics, Lens};
    let d = device();
    let mut splatter = Splatter::new(&d).unwrap();
    let city = demo_city(&DemoOptions { seed: 7, gaussians: 1000, sh_degree: 0 }).unwrap();
    let settings = SplatSettings { channels: Channels::default(), rgb: false, ..all_settings() };
    for (name, cam) in lens_cameras(&city) {
        let srug::scene::Projection::Pinhole { fx, fy, cx, cy } = cam.projection else { unreachable!() };
        let intr = Intrinsics {
            focal: [f64::from(fx), f64::from(fy)],
            centre: [f64::from(cx), f64::from(cy)],
            lens: cam.lens,
        };
        // A grid of directions over the image: unproject pixel-grid points to rays, place blobs 6 m out.
        let mut scene = Scene { sh_degree: 0, ..Scene::default() };
        let mut expected = Vec::new();
        let (w, h) = (f64::from(cam.width), f64::from(cam.height));
        for gy in 0..7 {
            for gx in 0..9 {
                let px = [(f64::from(gx) + 0.5) / 9.0 * w, (f64::from(gy) + 0.5) / 7.0 * h];
                let ray = match cam.lens {
                    Lens::Fisheye { .. } => {
                        // Keep within 80° off axis.
                        let Some(r) = intr.unproject(px) else { continue };
                        if (r[0] * r[0] + r[1] * r[1]).sqrt() > 80f64.to_radians().tan() {
                            continue;
                        }
                        [r[0], r[1], 1.0]
                    }
                    // All around, behind the camera too.
                    Lens::Equirectangular => cam.pixel_direction(px).unwrap(),
                    _ => {
                        let r = intr.unproject(px).unwrap();
                        [r[0], r[1], 1.0]
                    }
                };
                let dir = Vec3::new(ray[0] as f32, ray[1] as f32, ray[2] as f32).normalize();
                let p_cam = dir * 6.0;
                let world = cam.position + cam.rotation * p_cam;
                scene.means.push(world.to_array());
                scene.log_scales.push([-4.5; 3]);
                scene.rotations.push([1.0, 0.0, 0.0, 0.0]);
                scene.opacity_logits.push(4.0);
                scene.sh.extend([0.5, 0.5, 0.5]);
                let t = cam.world_to_camera(world);
                expected.push(intr.project([f64::from(t.x), f64::from(t.y), f64::from(t.z)]).unwrap());
            }
        }
        assert!(expected.len() >= 30, "{name}: {} blobs", expected.len());
        let gpu_scene = GpuScene::upload(&d, &scene).unwrap();
        let (out, _) = splatter.render(&gpu_scene, &cam, &settings).unwrap();
        let alpha = out.read(&d).unwrap().alpha;
        let (mut sum, mut worst) = (0.0f64, 0.0f64);
        for e in &expected {
            let (mut m, mut mx, mut my) = (0.0f64, 0.0f64, 0.0f64);
            let (x0, y0) = (e[0].floor() as i64, e[1].floor() as i64);
            for y in (y0 - 6).max(0)..(y0 + 7).min(i64::from(cam.height)) {
                for x in (x0 - 6).max(0)..(x0 + 7).min(i64::from(cam.width)) {
                    let a = f64::from(alpha[y as usize * cam.width as usize + x as usize]);
                    m += a;
                    mx += a * (x as f64 + 0.5);
                    my += a * (y as f64 + 0.5);
                }
            }
            assert!(m > 0.5, "{name}: no blob near {e:?}");
            let err = ((mx / m - e[0]).powi(2) + (my / m - e[1]).powi(2)).sqrt();
            sum += err;
            worst = worst.max(err);
        }
        let mean = sum / expected.len() as f64;
        println!("{name}: {} blobs, centroid error mean {mean:.4} px, max {worst:.4} px", expected.len());
        assert!(mean <= 0.1 && worst <= 0.5, "{name}: centroid error mean {mean} px, max {worst} px");
    }
    assert_no_validation_messages(&d);
}

#[test]
fn surface_depth_matches_cpu_twin_and_lies_on_the_surfaces() {
    let d = device();
    let mut splatter = Splatter::new(&d).unwrap();
    let settings = SplatSettings {
        channels: Channels { depth: true, median_depth: true, ..Channels::default() },
        prefill: Some(NAN),
        surface_depth: true,
        ..SplatSettings::default()
    };
    // Against the twin, on the demo city, through a pinhole camera and the
    // sun's orthographic light camera, with every blend variant.
    let city = demo_city(&DemoOptions { seed: 7, gaussians: 40_000, sh_degree: 1 }).unwrap();
    let sun = srug::shadow::Sun::from_azimuth_elevation(150.0, 40.0, [1.0; 3]).unwrap();
    let light = srug::shadow::light_camera(
        &city.scene.bounds().unwrap(),
        &sun,
        256,
        srug::shadow::ShadowFit::SceneBounds,
        None,
    )
    .unwrap();
    let cameras = [("pinhole", city.cameras[1].resized(352, 96)), ("orthographic", light)];
    let off = SplatSettings { surface_depth: false, ..settings };
    for (name, camera) in &cameras {
        for variant in blend_variants(&d) {
            splatter.set_blend_variant(variant).unwrap();
            let gpu =
                render_both(&d, &mut splatter, &city.scene, camera, &settings, &format!("surface_{name}_{variant:?}"));
            // The surface depth differs from the centre depth (the test is not vacuous).
            let (centre, _) = splatter.render(&GpuScene::upload(&d, &city.scene).unwrap(), camera, &off).unwrap();
            let centre = centre.read(&d).unwrap();
            let (a, b) = (gpu.get(Channel::Depth).unwrap(), centre.get(Channel::Depth).unwrap());
            let changed = a.iter().zip(b).filter(|(x, y)| (*x - *y).abs() > 1e-3).count();
            assert!(changed * 10 > a.len() / 10, "{name}: only {changed} of {} depths moved", a.len());
        }
    }
    // On the analytic block, the median depth of surface depths lies on the true
    // surfaces (ray cast against the exact geometry) far closer than centre depths.
    let block = srug::scene::blocks::block_city(&srug::scene::blocks::BlockOptions::default()).unwrap();
    let gpu_block = GpuScene::upload(&d, &block.scene).unwrap();
    let camera = &block.cameras[0];
    let (w, h) = (camera.width as usize, camera.height as usize);
    let truth: Vec<Option<f32>> = (0..w * h)
        .map(|p| {
            let dir = camera.pixel_direction([(p % w) as f64 + 0.5, (p / w) as f64 + 0.5])?;
            let world = camera.rotation * Vec3::new(dir[0] as f32, dir[1] as f32, dir[2] as f32);
            // Camera-space z of the hit: the direction has z = 1.
            block.hit(camera.position, world).map(|(t, _)| t)
        })
        .collect();
    let mut errors = Vec::new();
    for surface in [false, true] {
        let st = SplatSettings { surface_depth: surface, ..settings };
        let (g, _) = splatter.render(&gpu_block, camera, &st).unwrap();
        let median = g.read(&d).unwrap().get(Channel::MedianDepth).unwrap().to_vec();
        let pairs: Vec<f64> = median
            .iter()
            .zip(&truth)
            .filter_map(|(m, t)| t.filter(|_| *m > 0.0).map(|t| f64::from((m - t).abs() / t)))
            .collect();
        let mut sorted = pairs.clone();
        sorted.sort_by(f64::total_cmp);
        let mean = pairs.iter().sum::<f64>() / pairs.len() as f64;
        let (p50, p90) = (sorted[sorted.len() / 2], sorted[sorted.len() * 9 / 10]);
        eprintln!(
            "block median depth, surface depth {surface}: relative error median {p50:.2e}, 90% {p90:.2e}, mean {mean:.2e} over {} pixels",
            pairs.len()
        );
        errors.push(p50);
    }
    assert!(
        errors[1] < 0.25 * errors[0],
        "surface depth {:.2e} is not well below centre depth {:.2e}",
        errors[1],
        errors[0]
    );
    assert_no_validation_messages(&d);
}

#[test]
fn a_median_read_at_another_coverage_matches_cpu_twin() {
    // The median depth channel read where coverage 1 − T reaches 0.3 or 0.7
    // (shadow maps read theirs at more than one half), centre and surface
    // depths, through a pinhole camera and the sun's light camera, in every
    // blend variant; against the twin, and not the one-half median's image.
    let d = device();
    let mut splatter = Splatter::new(&d).unwrap();
    let city = demo_city(&DemoOptions { seed: 7, gaussians: 40_000, sh_degree: 1 }).unwrap();
    let gpu_scene = GpuScene::upload(&d, &city.scene).unwrap();
    let sun = srug::shadow::Sun::from_azimuth_elevation(150.0, 40.0, [1.0; 3]).unwrap();
    let bounds = city.scene.bounds().unwrap();
    let light = srug::shadow::light_camera(&bounds, &sun, 256, srug::shadow::ShadowFit::SceneBounds, None).unwrap();
    let cameras = [("pinhole", city.cameras[1].resized(352, 96)), ("orthographic", light)];
    let base = SplatSettings {
        channels: Channels { depth: true, median_depth: true, top_gaussian: true, ..Channels::default() },
        prefill: Some(NAN),
        ..SplatSettings::default()
    };
    let chosen = splatter.blend_variant();
    let covered = |g: &GBuffer| g.get(Channel::MedianDepth).unwrap().iter().filter(|z| **z > 0.0).count();
    for (name, camera) in &cameras {
        for surface_depth in [false, true] {
            let half = SplatSettings { surface_depth, ..base };
            let (g, _) = splatter.render(&gpu_scene, camera, &half).unwrap();
            let half_covered = covered(&g.read(&d).unwrap());
            for coverage in [0.3, 0.7] {
                let settings = SplatSettings { median_coverage: coverage, ..half };
                for variant in blend_variants(&d) {
                    splatter.set_blend_variant(variant).unwrap();
                    let label = format!("median_{coverage}_{name}_surface_{surface_depth}_{variant:?}");
                    let gpu = render_both(&d, &mut splatter, &city.scene, camera, &settings, &label);
                    // Less coverage needed, more pixels hold a median depth; more, fewer.
                    let n = covered(&gpu);
                    let expected = if coverage < 0.5 { n > half_covered } else { n < half_covered };
                    assert!(expected, "{label}: {n} pixels hold a median against {half_covered} at one half");
                }
            }
        }
    }
    for bad in [0.0, 1.0, f32::NAN, -0.2] {
        let settings = SplatSettings { median_coverage: bad, ..base };
        let text = splatter.render(&gpu_scene, &cameras[0].1, &settings).err().map(|e| e.to_string());
        let text = text.unwrap_or_default();
        assert!(text.contains(&format!("median coverage {bad}: must lie strictly between 0 and 1")), "{text:?}");
    }
    splatter.set_blend_variant(chosen).unwrap();
    assert_no_validation_messages(&d);
}

#[test]
fn a_host_depth_hides_the_splats_behind_it_as_the_twin_does() {
    use srug::splat::cpu::render_cpu_occluded;
    use srug::splat::HostDepth;
    let d = device();
    let mut splatter = Splatter::new(&d).unwrap();
    // Frames in front of a host's depth walk their lists whole, so the open
    // frame below does too, for rows with the same bits.
    splatter.set_chunk_length(0).unwrap();
    let city = demo_city(&DemoOptions { seed: 7, gaussians: 20_000, sh_degree: 1 }).unwrap();
    let scene = GpuScene::upload(&d, &city.scene).unwrap();
    let camera = city.cameras[1].resized(176, 48);
    let (w, h) = (camera.width as usize, camera.height as usize);
    // The host's meshes: a slanted wall from 8 m on the left to 38 m on the right,
    // and nothing at all in the top rows.
    let wall = |p: usize| if p / w < 6 { None } else { Some(8.0 + 30.0 * (p % w) as f64 / w as f64) };
    let (near, far) = (0.1f32, 200.0f32);
    let (n, f) = (f64::from(near), f64::from(far));
    // Each convention with how a host would store camera z in it (None: nothing there).
    type Encode = Box<dyn Fn(Option<f64>) -> f32>;
    let conventions: [(HostDepth, Encode); 4] = [
        (HostDepth::CameraZ, Box::new(|z: Option<f64>| z.map_or(0.0, |z| z as f32))),
        (
            HostDepth::Vulkan { near, far },
            Box::new(move |z: Option<f64>| z.map_or(1.0, |z| (f / (f - n) * (1.0 - n / z)) as f32)),
        ),
        (
            HostDepth::ReversedZ { near, far },
            Box::new(move |z: Option<f64>| z.map_or(0.0, |z| (n / (f - n) * (f / z - 1.0)) as f32)),
        ),
        (
            HostDepth::ReversedZ { near, far: f32::INFINITY },
            Box::new(move |z: Option<f64>| z.map_or(0.0, |z| (n / z) as f32)),
        ),
    ];
    let settings = SplatSettings {
        channels: Channels { depth: true, median_depth: true, ..Channels::default() },
        prefill: Some(NAN),
        ..SplatSettings::default()
    };
    let (open, _) = splatter.render(&scene, &camera, &settings).unwrap();
    let open = open.read(&d).unwrap();
    for (convention, encode) in &conventions {
        let values: Vec<f32> = (0..w * h).map(|p| encode(wall(p))).collect();
        for (p, v) in values.iter().enumerate() {
            let back = convention.camera_z(f64::from(*v));
            match wall(p) {
                Some(z) => assert!((back - z).abs() < 1e-3 * z, "{convention:?}: {z} → {v} → {back}"),
                None => assert!(back.is_infinite(), "{convention:?}: nothing → {v} → {back}"),
            }
        }
        let depth = d.upload("host depth", &values).unwrap();
        // Every blend variant with centre depths; surface depths (whose blend stops
        // later: a splat can be nearer than its centre) with the first convention.
        let surfaces: &[bool] = if *convention == HostDepth::CameraZ { &[false, true] } else { &[false] };
        for (variant, &surface) in blend_variants(&d).into_iter().flat_map(|v| surfaces.iter().map(move |s| (v, s))) {
            splatter.set_blend_variant(variant).unwrap();
            let settings = SplatSettings { surface_depth: surface, ..settings };
            let frame = splatter.render_frame_occluded(&scene, &camera, &settings, &depth, *convention).unwrap();
            // Never differentiated (the backward pass refuses it, below): no pair tiles.
            assert!(frame.pair_tiles.is_none());
            let gpu = frame.gbuffer.read(&d).unwrap();
            let cpu = render_cpu_occluded(&city.scene, &camera, &settings, &values, *convention);
            compare_with(&gpu, &cpu, &format!("occluded_{convention:?}_{variant:?}_surface{surface}"), true);
            // Not vacuous: the wall hides much of the street; where nothing is, nothing changes.
            let hidden = gpu.alpha.iter().zip(&open.alpha).filter(|(a, b)| **a + 0.05 < **b).count();
            assert!(hidden * 10 > w * h, "{convention:?}: only {hidden} pixels lost coverage");
            assert_eq!(&gpu.alpha[..6 * w], &open.alpha[..6 * w], "{convention:?}: rows without a host depth");
            if variant == BlendVariant::PerPixel && !surface {
                let e = splatter.backward(&frame, &scene, &srug::splat::backward::BlendGrads::default(), false);
                assert!(e.err().map(|e| e.to_string()).unwrap_or_default().contains("host's depth"));
            }
        }
    }
    // Clear refusals: a buffer too small, impossible planes.
    let small = d.upload("small", &[1.0f32; 16]).unwrap();
    let e = splatter.render_frame_occluded(&scene, &camera, &settings, &small, HostDepth::CameraZ).err().unwrap();
    assert!(e.to_string().contains("host depth buffer of 64 bytes"), "{e}");
    let depth = d.upload("host depth", &vec![1.0f32; w * h]).unwrap();
    for bad in [HostDepth::Vulkan { near: 0.0, far: 1.0 }, HostDepth::Vulkan { near: 1.0, far: f32::INFINITY }] {
        let e = splatter.render_frame_occluded(&scene, &camera, &settings, &depth, bad).err().unwrap();
        assert!(e.to_string().contains("need 0 < near < far"), "{e}");
    }
    assert_no_validation_messages(&d);
}

#[test]
fn blend_work_counts_the_longest_walk() {
    // Ten splats at one place, 50 m across at 10 m from the camera: every
    // pixel sees α = 0.99 (the clamp) from each. T falls to 0.01, then 1e-4
    // (still ≥ 1e-4: taken), and the third would take it below 1e-4: it
    // ends the walk, so every pixel reads three. Faint ones (opacity 0.018)
    // never end it: every pixel reads all ten.
    let mut scene = random_scene(10, 0, 5, 1.0);
    scene.means = vec![[0.0; 3]; 10];
    for (l, r) in scene.log_scales.iter_mut().zip(&mut scene.rotations) {
        *l = [50f32.ln(); 3];
        *r = [1.0, 0.0, 0.0, 0.0];
    }
    scene.opacity_logits = vec![12.0; 10];
    let camera = Camera::look_at(Vec3::new(0.0, -10.0, 0.0), Vec3::ZERO, Vec3::Z, 60.0, 40, 24).unwrap();
    let work = blend_work(&scene, &camera, 16, TileBounds::Ellipse);
    let pixels = 40 * 24;
    assert_eq!((work.longest_walk, work.evaluated, work.contributed), (3, 3 * pixels, 2 * pixels), "{work:?}");
    scene.opacity_logits = vec![-4.0; 10];
    let work = blend_work(&scene, &camera, 16, TileBounds::Ellipse);
    assert_eq!((work.longest_walk, work.evaluated, work.contributed), (10, 10 * pixels, 10 * pixels), "{work:?}");
}

/// The preprocess stores each splat's ten features at 16 bits (`pack_features` in
/// `splat_types.glsl`): every Gaussian the GPU lists that the twin also sees stores the twin's
/// packing of its f64 features but for f32 rounding (one step at most in any value: the demo's
/// roughness 0.9 lies on a rounding tie at 16 bits), and unpacked they lie within one step
/// (1/32767 for the normal, 1/65535 for the rest) plus f32 rounding of the twin's features.
#[test]
fn features_are_stored_at_16_bits_as_the_twin_packs_them() {
    let d = device();
    let mut splatter = Splatter::new(&d).unwrap();
    let city = demo_city(&DemoOptions { seed: 7, gaussians: 30_000, sh_degree: 1 }).unwrap();
    let cam = city.cameras[1].resized(352, 96);
    let settings = SplatSettings { packed_features: true, ..all_settings() };
    let gpu_scene = GpuScene::upload(&d, &city.scene).unwrap();
    let frame = splatter.render_frame(&gpu_scene, &cam, &settings).unwrap();
    assert!(frame.packed_features);
    let words: Vec<u32> = d.read_buffer(frame.features.as_ref().unwrap()).unwrap();
    let offsets: Vec<u32> = d.read_buffer(&frame.pair_offsets).unwrap();
    assert_eq!(words.len(), 6 * city.scene.len(), "24 bytes a Gaussian");
    let (mut compared, mut twin_only) = (0usize, 0usize);
    for i in 0..city.scene.len() {
        let Some(twin) = preprocess_one(&city.scene, i, &cam, NormalSource::Stored, DEFAULT_TILE) else {
            continue;
        };
        let twin_pairs: u32 =
            (twin.rect[1]..twin.rect[3]).map(|ty| tile_row_span(&twin, ty, DEFAULT_TILE)).map(|(x0, x1)| x1 - x0).sum();
        if offsets[i + 1] == offsets[i] {
            // Listed in no tile, so its features are not written: the twin lists none either,
            // but where f32 rounding at the ellipse's bound differs from f64.
            twin_only += usize::from(twin_pairs > 0);
            continue;
        }
        compared += 1;
        let gpu: [u32; 6] = words[6 * i..6 * i + 6].try_into().unwrap();
        let packed = pack_features(&twin.features);
        for (w, (g, c)) in gpu.iter().zip(&packed).enumerate() {
            for half in [0, 16] {
                let (g, c) = ((g >> half) & 0xffff, (c >> half) & 0xffff);
                let steps = g.abs_diff(c).min(0x10000 - g.abs_diff(c));
                assert!(steps <= 1, "Gaussian {i} word {w} bits {half}..: stored {g:#x}, twin {c:#x}");
            }
        }
        for (k, (g, c)) in unpack_features(&gpu).iter().zip(&twin.features).enumerate() {
            let step = if k < 3 { 1.0 / 32767.0 } else { 1.0 / 65535.0 };
            assert!((g - c).abs() <= step + 1e-6, "Gaussian {i} feature {k}: stored {g}, twin {c}");
        }
    }
    assert!(compared > 5_000, "only {compared} Gaussians in view");
    assert!(twin_only * 1000 <= compared, "{twin_only} Gaussians the twin lists were not listed, of {compared}");
    // The G-buffer's features are the blend of what was stored: within the twin comparison's tolerances.
    let packed = frame.gbuffer.read(&d).unwrap();
    compare(&packed, &render_cpu(&city.scene, &cam, &settings), "packed_features");
    // Against the same frame with float features, on every blend path: rgb, alpha and the
    // depths bit for bit, normal and materials within one 16-bit step.
    for texel in [true, false] {
        splatter.set_texel_blend(texel).unwrap();
        let floats = splatter.render_frame(&gpu_scene, &cam, &all_settings()).unwrap();
        assert!(!floats.packed_features);
        let floats = floats.gbuffer.read(&d).unwrap();
        let packed = splatter.render_frame(&gpu_scene, &cam, &settings).unwrap().gbuffer.read(&d).unwrap();
        for ((name, p, _), (_, f, _)) in packed.channels().into_iter().zip(floats.channels()) {
            let worst = p.iter().zip(f).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
            let limit = match name {
                "normal" => 1.0 / 32767.0 + 1e-6,
                "albedo" | "roughness" | "metallic" | "ao" | "visibility" => 1.0 / 65535.0 + 1e-6,
                _ => 0.0,
            };
            assert!(worst <= limit, "texel blend {texel}: {name} differs by {worst} (limit {limit})");
        }
    }
    // The backward pass refuses feature gradients of a packed frame.
    let albedo = d.create_filled::<f32>("d albedo", 3 * 352 * 96, 0).unwrap();
    let grads = BlendGrads { channels: PerChannel::default().with(Channel::Albedo, albedo), ..BlendGrads::default() };
    let e = splatter.backward(&frame, &gpu_scene, &grads, false).err().unwrap().to_string();
    assert!(e.contains("packed_features"), "{e}");
    assert_no_validation_messages(&d);
}

/// Compacted records (`SplatSettings::compact_splats`): a frame keeps records only for the
/// Gaussians its position cull keeps, in increasing order, each the record the full frame gives
/// that Gaussian bit for bit (tile count, splat, features), every Gaussian the full frame lists
/// among them, and the twin's listed Gaussians too (but 1 in 1000 at f32 rounding of the
/// ellipse's bound); the G-buffers, top-Gaussian ids included, are the full frame's bit for bit
/// on both blend and both preprocess paths, for several cameras in one call (one looking at
/// nothing), and on a scene arranged in Morton order (whose ids map twice).
#[test]
fn compacted_records_are_the_listed_gaussians_and_the_frames_the_same_bits() {
    let d = device();
    let mut splatter = Splatter::new(&d).unwrap();
    let city = demo_city(&DemoOptions { seed: 11, gaussians: 30_000, sh_degree: 1 }).unwrap();
    let mut cams: Vec<Camera> = city.cameras.iter().take(2).map(|c| c.resized(352, 96)).collect();
    let away = Camera::look_at(Vec3::new(0.0, 0.0, 500.0), Vec3::new(0.0, 0.0, 1000.0), Vec3::Y, 60.0, 64, 48).unwrap();
    cams.push(away);
    let full_settings = SplatSettings { packed_features: true, ..all_settings() };
    let settings = SplatSettings { compact_splats: true, ..full_settings };
    let n = city.scene.len();
    let mut gpu_scene = GpuScene::upload(&d, &city.scene).unwrap();
    for (texel_blend, texel_preprocess) in [(true, true), (false, false)] {
        splatter.set_texel_blend(texel_blend).unwrap();
        splatter.set_texel_preprocess(texel_preprocess).unwrap();
        let full = splatter.render_frames(&gpu_scene, &cams, &full_settings).unwrap();
        let compact = splatter.render_frames(&gpu_scene, &cams, &settings).unwrap();
        for (k, (f, c)) in full.iter().zip(&compact).enumerate() {
            let label = format!("camera {k}, texel blend {texel_blend}, texel preprocess {texel_preprocess}");
            assert_eq!(f.stats.records, n as u64, "{label}");
            assert!(f.slot_gaussians.is_none(), "{label}");
            assert_eq!(c.stats.pairs, f.stats.pairs, "{label}");
            let stages = |f: &srug::splat::SplatFrame| -> Vec<String> {
                f.stats.timings.stages.iter().map(|s| s.name.clone()).collect()
            };
            assert_eq!(stages(c)[0], "cull", "{label}: the first pass");
            assert!(stages(c).iter().all(|n| SPLAT_STAGES.contains(&n.as_str())), "{label}: {:?}", stages(c));
            assert!(!stages(f).contains(&"cull".to_string()), "{label}: {:?}", stages(f));
            assert!(c.stats.working_bytes < f.stats.working_bytes, "{label}");
            let (a, b) = (gbuffer_bits(&c.gbuffer.read(&d).unwrap()), gbuffer_bits(&f.gbuffer.read(&d).unwrap()));
            assert_eq!(a.len(), b.len(), "{label}");
            let differing = a.iter().zip(&b).filter(|(x, y)| x != y).count();
            assert_eq!(differing, 0, "{label}: {differing} G-buffer values differ");
            let slots: Vec<u32> = d.read_buffer(c.slot_gaussians.as_ref().unwrap()).unwrap();
            assert_eq!(slots.len() as u64, c.stats.records, "{label}");
            assert!(slots.windows(2).all(|w| w[0] < w[1]), "{label}: slots out of order");
            let full_offsets: Vec<u32> = d.read_buffer(&f.pair_offsets).unwrap();
            let offsets: Vec<u32> = d.read_buffer(&c.pair_offsets).unwrap();
            let full_splats: Vec<u32> = d.read_buffer(&f.splats).unwrap();
            let splats: Vec<u32> = d.read_buffer(&c.splats).unwrap();
            let full_features: Vec<u32> = d.read_buffer(f.features.as_ref().unwrap()).unwrap();
            let features: Vec<u32> = d.read_buffer(c.features.as_ref().unwrap()).unwrap();
            let listed = (0..n).filter(|&i| full_offsets[i + 1] > full_offsets[i]).count();
            let mut kept = 0;
            for (slot, &i) in slots.iter().enumerate() {
                let i = i as usize;
                let pairs = offsets[slot + 1] - offsets[slot];
                assert_eq!(pairs, full_offsets[i + 1] - full_offsets[i], "{label}: Gaussian {i}'s tile count");
                if pairs > 0 {
                    kept += 1;
                    assert_eq!(
                        splats[16 * slot..16 * slot + 16],
                        full_splats[16 * i..16 * i + 16],
                        "{label}: Gaussian {i}"
                    );
                    assert_eq!(
                        features[6 * slot..6 * slot + 6],
                        full_features[6 * i..6 * i + 6],
                        "{label}: Gaussian {i}"
                    );
                }
            }
            assert_eq!(kept, listed, "{label}: Gaussians listed by the full frame without a record");
            if k == 2 {
                assert_eq!((c.stats.records, c.stats.pairs), (0, 0), "{label}: a view of nothing");
                continue;
            }
            assert!(
                listed > 2_000 && c.stats.records < n as u64 * 3 / 4,
                "{label}: {listed} listed, {} records",
                c.stats.records
            );
            let mut twin_only = 0;
            for i in 0..n {
                let Some(twin) = preprocess_one(&city.scene, i, &cams[k], NormalSource::Stored, DEFAULT_TILE) else {
                    continue;
                };
                let pairs: u32 = (twin.rect[1]..twin.rect[3])
                    .map(|ty| tile_row_span(&twin, ty, DEFAULT_TILE))
                    .map(|(x0, x1)| x1 - x0)
                    .sum();
                twin_only += usize::from(pairs > 0 && slots.binary_search(&(i as u32)).is_err());
            }
            assert!(twin_only * 1000 <= listed, "{label}: {twin_only} Gaussians the twin lists have no record");
        }
    }
    // The twin's image, and an arranged scene's ids through both maps.
    let frame = splatter.render_frame(&gpu_scene, &cams[0], &settings).unwrap();
    compare(&frame.gbuffer.read(&d).unwrap(), &render_cpu(&city.scene, &cams[0], &settings), "compacted");
    assert!(gpu_scene.arrange(&d, SceneOrder::Morton).unwrap());
    let full = splatter.render_frame(&gpu_scene, &cams[0], &full_settings).unwrap().gbuffer.read(&d).unwrap();
    let compact = splatter.render_frame(&gpu_scene, &cams[0], &settings).unwrap().gbuffer.read(&d).unwrap();
    assert_eq!(compact.top_gaussian, full.top_gaussian, "arranged scene's ids");
    assert!(full.top_gaussian.as_ref().unwrap().iter().any(|&id| id != u32::MAX));
    // The backward pass refuses a compacted frame.
    let e = splatter.backward(&frame, &gpu_scene, &BlendGrads::default(), false).err().unwrap().to_string();
    assert!(e.contains("compact_splats"), "{e}");
    assert_no_validation_messages(&d);
}
