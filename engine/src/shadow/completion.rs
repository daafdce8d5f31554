//! Shadow-guided completion: Gaussians that no camera sees are optimised so
//! the shadows they cast match a target (the paper's shadow guidance).
//!
//! The scene as given casts its shadows through a median-depth shadow map,
//! rendered once (V_scene). The added Gaussians get their own shadow map in
//! expected-over-far depth — differentiable even where they are still faint —
//! from the same light camera, fitted once so texels stay put while Gaussians
//! move; their visibility V_added multiplies (independent occluders):
//! V = V_scene·V_added. Each step takes the paper's visibility loss
//! BCE(V_added, V_target) over the receivers the scene leaves lit, back through
//! the sigmoid shadow test and the added map's splat to the added Gaussians,
//! and moves them with Adam.
//!
//! The initial Gaussians fill the region that can shadow the view but that no
//! camera sees: the box spanned by the sun rays from every receiver in view,
//! minus every point a camera sees. The optimisation has to carve the
//! occluder out of that cloud.
//!
//! The receivers are the input scene's, rendered once: the added Gaussians
//! start outside every view (their centres; [`Completion::visible_added`]
//! counts those that end inside one).

use glam::{DVec3, Vec3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

use super::backward::GpuVisibilityLoss;
use super::cpu::{unproject, DepthImage};
use super::{light_camera, DepthMode, ShadowFit, ShadowPass, ShadowSettings, Sun, VisibilityKind};
use crate::error::{Error, Result};
use crate::gpu::Device;
use crate::scene::activate::GpuScene;
use crate::scene::{sh_coefficients, Bounds, Camera, Scene};
use crate::splat::{Channels, SplatSettings, Splatter};

/// Knobs of [`complete_from_shadow`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CompletionSettings {
    /// Adam steps.
    pub steps: u32,
    /// Gaussians added.
    pub gaussians: usize,
    /// The shadow test (resolution, k, bias, the scene map's depth mode, receivers).
    pub shadow: ShadowSettings,
    /// Learning rates: means (in units of the initial Gaussian size), log-scales,
    /// rotations, opacity logits.
    pub learning_rates: [f32; 4],
    /// Initial opacity logit of the added Gaussians.
    pub initial_opacity_logit: f32,
    /// Seed of the initial placement.
    pub seed: u64,
}

impl Default for CompletionSettings {
    fn default() -> Self {
        Self {
            steps: 60,
            gaussians: 4000,
            shadow: ShadowSettings {
                resolution: 256,
                k: 4.0,
                bias: 0.3,
                // Differentiable receivers (expected depth), no normals rendered: no slope bias.
                slope_bias: 0.0,
                map_depth: super::DepthMode::Median,
                receiver_depth: super::DepthMode::Expected,
                fit: ShadowFit::ViewFrustum,
                ..ShadowSettings::default()
            },
            learning_rates: [0.025, 0.025, 0.01, 0.1],
            initial_opacity_logit: -4.0,
            seed: 1,
        }
    }
}

/// One step's figures.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CompletionStep {
    /// Step index (0 is the initial state).
    pub step: u32,
    /// Mean BCE over the receivers the scene leaves lit.
    pub loss: f64,
    /// IoU of the shadowed pixels (V < 0.5) against the target's, over every receiver.
    pub iou: f64,
    /// The same over the receivers the scene alone leaves lit: how well the
    /// missing shadow is recovered (0 for the scene alone).
    pub missing_iou: f64,
}

/// What [`complete_from_shadow`] produced.
pub struct Completion {
    /// The input scene with the optimised Gaussians appended.
    pub scene: Scene,
    /// Index of the first added Gaussian.
    pub first_added: usize,
    /// Visibility of the scene alone.
    pub without: Vec<f32>,
    /// Visibility with the initial Gaussians.
    pub before: Vec<f32>,
    /// Visibility with the optimised Gaussians.
    pub after: Vec<f32>,
    /// Receivers with a surface (where IoU is measured).
    pub mask: Vec<bool>,
    /// Per-step loss and IoU (the first entry is the initial state).
    pub history: Vec<CompletionStep>,
    /// Added Gaussians whose centre ended inside a camera's view.
    pub visible_added: usize,
}

/// IoU of the shadowed sets (V < 0.5) of `a` and `b` over pixels where `mask`.
pub fn shadow_iou(a: &[f32], b: &[f32], mask: &[bool]) -> f64 {
    let (mut inter, mut union) = (0usize, 0usize);
    for ((x, y), m) in a.iter().zip(b).zip(mask) {
        if *m {
            let (sx, sy) = (*x < 0.5, *y < 0.5);
            inter += usize::from(sx && sy);
            union += usize::from(sx || sy);
        }
    }
    if union == 0 {
        1.0
    } else {
        inter as f64 / union as f64
    }
}

struct Adam {
    m: Vec<f32>,
    v: Vec<f32>,
    t: i32,
}

impl Adam {
    fn new(n: usize) -> Self {
        Self { m: vec![0.0; n], v: vec![0.0; n], t: 0 }
    }

    /// One Adam step (β = 0.9, 0.999) on `params` with per-entry learning rates `lr(i)`.
    fn step(&mut self, params: &mut [f32], grads: &[f32], lr: impl Fn(usize) -> f32) {
        self.t += 1;
        let (b1, b2) = (0.9f32, 0.999f32);
        let (c1, c2) = (1.0 - b1.powi(self.t), 1.0 - b2.powi(self.t));
        for (i, (p, g)) in params.iter_mut().zip(grads).enumerate() {
            let g = if g.is_finite() { *g } else { 0.0 };
            self.m[i] = b1 * self.m[i] + (1.0 - b1) * g;
            self.v[i] = b2 * self.v[i] + (1.0 - b2) * g * g;
            *p -= lr(i) * (self.m[i] / c1) / ((self.v[i] / c2).sqrt() + 1e-12);
        }
    }
}

/// Optimises Gaussians added to `scene` so the shadows seen from `camera`
/// under `sun` match `target` (per-pixel visibility, e.g. rendered with the
/// missing geometry present). `region` bounds where occluders may be (the
/// light camera covers it, the initial Gaussians stay in it): the scene's
/// bounds or wider, since what is missing may lie outside them. `cameras` are
/// every view: initial Gaussians are placed where none of them sees.
/// `progress` gets every step's figures.
#[allow(clippy::too_many_arguments, reason = "the problem is defined by these independent inputs")]
pub fn complete_from_shadow(
    device: &Device,
    scene: &Scene,
    region: &Bounds,
    camera: &Camera,
    cameras: &[Camera],
    sun: &Sun,
    target: &[f32],
    settings: &CompletionSettings,
    progress: &mut dyn FnMut(&CompletionStep),
) -> Result<Completion> {
    let pixels = (camera.width * camera.height) as usize;
    if target.len() != pixels || target.iter().any(|v| !v.is_finite()) {
        return Err(Error::invalid(
            format!("target visibility of {} values", target.len()),
            format!("needs {pixels} finite values for the {}x{} camera", camera.width, camera.height),
        ));
    }
    let st = settings.shadow;
    let added_st = ShadowSettings { map_depth: DepthMode::ExpectedOverFar, ..st };
    let mut splatter = Splatter::new(device)?;
    let mut pass = ShadowPass::new(device)?;
    let receiver_settings = SplatSettings {
        channels: Channels { depth: true, median_depth: true, ..Channels::default() },
        ..SplatSettings::default()
    };

    // The scene as given: its receivers and its own shadows, once.
    let gpu = GpuScene::upload(device, scene)?;
    let receivers = splatter.render_frame(&gpu, camera, &receiver_settings)?;
    let host = receivers.gbuffer.read(device)?;
    let bounds = *region;
    let light = light_camera(&bounds, sun, st.resolution, st.fit, Some(camera))?;
    let map = pass.shadow_map_from(&mut splatter, &gpu, light.clone(), sun, &st)?;
    let (v, _) = pass.visibility(&map, &receivers.gbuffer, camera, &st, VisibilityKind::Sigmoid)?;
    let without: Vec<f32> = device.read_buffer(&v)?;
    drop(map);
    let mask: Vec<bool> = host.alpha.iter().map(|a| *a >= st.min_alpha).collect();

    // Initial Gaussians: in the box of sun rays from the receivers, where no camera sees.
    let img = DepthImage::from_gbuffer(&host);
    let mut lo = DVec3::splat(f64::MAX);
    let mut hi = DVec3::splat(f64::MIN);
    let d = sun.direction.as_dvec3();
    let reach = f64::from((Vec3::from_array(bounds.max) - Vec3::from_array(bounds.min)).length());
    for (p, covered) in mask.iter().enumerate() {
        if !covered {
            continue;
        }
        let Some(z) = img.depth(st.receiver_depth, p, f64::from(st.min_alpha), 0.0) else { continue };
        let x = unproject(camera, p, z);
        for t in [1.0, reach] {
            let q = x + d * t;
            lo = lo.min(q);
            hi = hi.max(q);
        }
    }
    if lo.x > hi.x {
        return Err(Error::invalid("receivers", "none in view has a surface"));
    }
    lo = lo.max(DVec3::from_array(bounds.min.map(f64::from)));
    hi = hi.min(DVec3::from_array(bounds.max.map(f64::from)) + DVec3::new(0.0, 0.0, 0.5 * reach));
    let mut rng = Pcg64Mcg::seed_from_u64(settings.seed);
    let mut added = Scene { sh_degree: scene.sh_degree, ..Scene::default() };
    let k = sh_coefficients(scene.sh_degree);
    let volume = (hi - lo).max(DVec3::splat(1e-3));
    let scale = ((volume.x * volume.y * volume.z / settings.gaussians.max(1) as f64).cbrt()).max(1e-3) as f32;
    let mut tries = 0usize;
    while added.means.len() < settings.gaussians && tries < settings.gaussians * 200 {
        tries += 1;
        let p = Vec3::new(
            rng.random_range(lo.x..=hi.x) as f32,
            rng.random_range(lo.y..=hi.y) as f32,
            rng.random_range(lo.z..=hi.z) as f32,
        );
        if cameras.iter().chain([camera]).any(|c| c.sees(p)) {
            continue;
        }
        added.means.push(p.to_array());
        added.log_scales.push([scale.ln(); 3]);
        added.rotations.push([1.0, 0.0, 0.0, 0.0]);
        added.opacity_logits.push(settings.initial_opacity_logit);
        added.sh.extend(std::iter::repeat_n(0.0, 3 * k));
    }
    if added.means.is_empty() {
        return Err(Error::invalid("occluder region", "every point of it is seen by a camera"));
    }
    let added_gpu = GpuScene::upload(device, &added)?;

    // The added Gaussians answer for the receivers the scene leaves lit.
    let added_target: Vec<f32> = target.iter().zip(&without).map(|(t, w)| if *w >= 0.5 { *t } else { -1.0 }).collect();
    let target_buf = device.upload("shadow target", &added_target)?;
    let lit_mask: Vec<bool> = mask.iter().zip(&without).map(|(m, w)| *m && *w >= 0.5).collect();
    let n = added.means.len();
    let mut params: Vec<f32> = Vec::with_capacity(n * 11);
    for i in 0..n {
        params.extend(added.means[i]);
        params.extend(added.log_scales[i]);
        params.extend(added.rotations[i]);
        params.push(added.opacity_logits[i]);
    }
    let mut adam = Adam::new(params.len());
    let lrs = settings.learning_rates;
    let lr = |i: usize| match i % 11 {
        0..=2 => lrs[0] * scale,
        3..=5 => lrs[1],
        6..=9 => lrs[2],
        _ => lrs[3],
    };
    let mut history = Vec::new();
    let mut before = Vec::new();
    let mut after = Vec::new();
    for step in 0..=settings.steps {
        let (mut m, mut ls, mut r, mut o) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for chunk in params.chunks(11) {
            m.extend_from_slice(&chunk[0..3]);
            ls.extend_from_slice(&chunk[3..6]);
            r.extend_from_slice(&chunk[6..10]);
            o.push(chunk[10]);
        }
        device.write_buffer(&added_gpu.means, 0, &m)?;
        device.write_buffer(&added_gpu.log_scales, 0, &ls)?;
        device.write_buffer(&added_gpu.rotations, 0, &r)?;
        device.write_buffer(&added_gpu.opacity_logits, 0, &o)?;

        let map = pass.shadow_map_from(&mut splatter, &added_gpu, light.clone(), sun, &added_st)?;
        let (v, _) = pass.visibility(&map, &receivers.gbuffer, camera, &added_st, VisibilityKind::Sigmoid)?;
        let v_added: Vec<f32> = device.read_buffer(&v)?;
        let v: Vec<f32> = v_added.iter().zip(&without).map(|(a, b)| a * b).collect();
        let b = pass.backward(&map, &receivers.gbuffer, camera, &added_st, GpuVisibilityLoss::Bce(&target_buf))?;
        let figures = CompletionStep {
            step,
            loss: b.loss,
            iou: shadow_iou(&v, target, &mask),
            missing_iou: shadow_iou(&v, target, &lit_mask),
        };
        progress(&figures);
        history.push(figures);
        if step == 0 {
            before = v.clone();
        }
        if step == settings.steps {
            after = v;
            break;
        }
        let g = splatter.backward(&map.frame, &added_gpu, &b.map, false)?.read(device)?;
        let mut grads = vec![0.0f32; params.len()];
        for (i, gi) in grads.chunks_mut(11).enumerate() {
            gi[0..3].copy_from_slice(&g.means[i]);
            gi[3..6].copy_from_slice(&g.log_scales[i]);
            gi[6..10].copy_from_slice(&g.rotations[i]);
            gi[10] = g.opacity_logits[i];
        }
        // Learning rates decay linearly to a tenth over the run.
        let decay = 1.0 - 0.9 * step as f32 / settings.steps.max(1) as f32;
        adam.step(&mut params, &grads, |i| lr(i) * decay);
        for chunk in params.chunks_mut(11) {
            for s in &mut chunk[3..6] {
                *s = s.clamp((1e-2 * scale).ln(), (10.0 * scale).ln());
            }
            chunk[10] = chunk[10].clamp(-12.0, 12.0);
        }
    }
    for (i, chunk) in params.chunks(11).enumerate() {
        added.means[i] = [chunk[0], chunk[1], chunk[2]];
        added.log_scales[i] = [chunk[3], chunk[4], chunk[5]];
        added.rotations[i] = [chunk[6], chunk[7], chunk[8], chunk[9]];
        added.opacity_logits[i] = chunk[10];
    }
    let visible_added =
        added.means.iter().filter(|p| cameras.iter().chain([camera]).any(|c| c.sees(Vec3::from_array(**p)))).count();
    let first_added = scene.len();
    let mut completed = scene.clone();
    append(&mut completed, &added);
    Ok(Completion { scene: completed, first_added, without, before, after, mask, history, visible_added })
}

/// Appends `b`'s Gaussians to `a` (optional attributes padded with neutral values).
fn append(a: &mut Scene, b: &Scene) {
    let n = b.means.len();
    a.means.extend(&b.means);
    a.log_scales.extend(&b.log_scales);
    a.rotations.extend(&b.rotations);
    a.opacity_logits.extend(&b.opacity_logits);
    a.sh.extend(&b.sh);
    if let Some(v) = &mut a.normals {
        v.extend(std::iter::repeat_n([0.0; 3], n));
    }
    let m = &mut a.materials;
    if let Some(v) = &mut m.albedo {
        v.extend(std::iter::repeat_n([0.0; 3], n));
    }
    for v in [&mut m.roughness, &mut m.metallic, &mut m.ao, &mut m.visibility].into_iter().flatten() {
        v.extend(std::iter::repeat_n(0.0, n));
    }
}

/// The demo's completion problem: the demo city without the Gaussians of its
/// off-screen tower (those within half a metre of its box).
pub fn without_offscreen_tower(demo: &crate::scene::demo::DemoCity) -> Scene {
    let t = demo.offscreen_tower;
    let keep: Vec<bool> = demo
        .scene
        .means
        .iter()
        .map(|p| {
            let p = Vec3::from_array(*p);
            !(p.cmpge(t.min - 0.5).all() && p.cmple(t.max + 0.5).all())
        })
        .collect();
    demo.scene.select(&keep)
}

/// The demo's shadow-guided completion, as `srug shadow-fit` runs it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DemoCompletion {
    /// Demo city size and seed.
    pub demo: crate::scene::demo::DemoOptions,
    /// Which default camera receives the shadow.
    pub camera: usize,
    /// Receiver image size.
    pub size: (u32, u32),
    /// Sun (azimuth, elevation) in degrees: the default puts the tower's shadow
    /// on a lit part of the first camera's view.
    pub sun: (f32, f32),
    /// The optimisation.
    pub settings: CompletionSettings,
}

impl Default for DemoCompletion {
    fn default() -> Self {
        Self {
            demo: crate::scene::demo::DemoOptions { gaussians: 40_000, ..Default::default() },
            camera: 0,
            size: (352, 96),
            sun: (260.0, 50.0),
            settings: CompletionSettings::default(),
        }
    }
}

/// [`DemoCompletion`]'s problem and result.
pub struct DemoCompletionResult {
    /// The receiving camera.
    pub camera: Camera,
    /// The target visibility (the tower present).
    pub target: Vec<f32>,
    /// Gaussians removed with the tower.
    pub removed: usize,
    /// The completion.
    pub completion: Completion,
}

/// Removes the demo's off-screen tower, renders the shadow it cast as the
/// target, and completes the scene from that shadow.
pub fn complete_demo(
    device: &Device,
    options: &DemoCompletion,
    progress: &mut dyn FnMut(&CompletionStep),
) -> Result<DemoCompletionResult> {
    let demo = crate::scene::demo::demo_city(&options.demo)?;
    let base = demo.cameras.get(options.camera).ok_or_else(|| {
        Error::invalid(
            format!("camera {}", options.camera),
            format!("does not exist (the demo has {})", demo.cameras.len()),
        )
    })?;
    let camera = base.resized(options.size.0, options.size.1);
    let sun = Sun::from_azimuth_elevation(options.sun.0, options.sun.1, [1.0; 3])?;
    if !sun.above_horizon() {
        return Err(Error::invalid("sun", "must be above the horizon to cast a shadow"));
    }
    let without = without_offscreen_tower(&demo);
    let st = options.settings.shadow;
    // The target: the full scene's shadow, from the light camera the completion will use.
    let mut splatter = Splatter::new(device)?;
    let pass = ShadowPass::new(device)?;
    let full = GpuScene::upload(device, &demo.scene)?;
    let channels = Channels { depth: true, median_depth: true, ..Channels::default() };
    let receivers = splatter.render_frame(&full, &camera, &SplatSettings { channels, ..SplatSettings::default() })?;
    // Occluders may be anywhere in the city's extent (the tower included: what is
    // removed is unknown to the fit, the extent of the place is not).
    let bounds = demo.scene.bounds().ok_or_else(|| Error::invalid("demo scene", "is empty"))?;
    let light = light_camera(&bounds, &sun, st.resolution, st.fit, Some(&camera))?;
    let map = pass.shadow_map_from(&mut splatter, &full, light, &sun, &st)?;
    let (v, _) = pass.visibility(&map, &receivers.gbuffer, &camera, &st, VisibilityKind::Sigmoid)?;
    let target: Vec<f32> = device.read_buffer(&v)?;
    let completion = complete_from_shadow(
        device,
        &without,
        &bounds,
        &camera,
        &demo.cameras,
        &sun,
        &target,
        &options.settings,
        progress,
    )?;
    Ok(DemoCompletionResult { camera, target, removed: demo.scene.len() - without.len(), completion })
}
