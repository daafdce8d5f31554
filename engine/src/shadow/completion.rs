//! Shadow-guided completion: Gaussians that no camera sees are optimised so
//! the shadows they cast match a target (the paper's shadow guidance).
//!
//! Each step renders the receivers and the shadow map, takes the paper's
//! visibility loss BCE(V_e, V_target) back through the sigmoid shadow test and
//! both splats (shadow map and receivers) to the Gaussians, and moves only the
//! added Gaussians with Adam. The light camera is fitted once, so the map's
//! texels stay put while Gaussians move.
//!
//! The initial Gaussians fill the region that can shadow the view but that no
//! camera sees: the box spanned by the sun rays from every receiver in view,
//! minus every point a camera sees. Their shadow covers most of the view at
//! first, so the optimisation has to carve the occluder out of the cloud.
//!
//! The receivers are the input scene's, rendered once: the added Gaussians
//! start outside every view (their centres, checked again at the end), so
//! only the shadow map sees them and only its backward pass runs per step.

use glam::{DVec3, Vec3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

use super::backward::GpuVisibilityLoss;
use super::cpu::{unproject, DepthImage};
use super::{light_camera, ShadowFit, ShadowPass, ShadowSettings, Sun, VisibilityKind};
use crate::error::{Error, Result};
use crate::gpu::Device;
use crate::scene::activate::GpuScene;
use crate::scene::{sh_coefficients, Camera, Scene};
use crate::splat::{Channels, SplatSettings, Splatter};

/// Knobs of [`complete_from_shadow`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CompletionSettings {
    /// Adam steps.
    pub steps: u32,
    /// Gaussians added.
    pub gaussians: usize,
    /// The shadow test (resolution, k, bias, depth modes).
    pub shadow: ShadowSettings,
    /// Learning rates: means (world units), log-scales, rotations, opacity logits.
    pub learning_rates: [f32; 4],
    /// Seed of the initial placement.
    pub seed: u64,
}

impl Default for CompletionSettings {
    fn default() -> Self {
        Self {
            steps: 60,
            gaussians: 3000,
            shadow: ShadowSettings {
                resolution: 256,
                k: 4.0,
                bias: 0.3,
                map_depth: super::DepthMode::Expected,
                receiver_depth: super::DepthMode::Expected,
                fit: ShadowFit::ViewFrustum,
                ..ShadowSettings::default()
            },
            learning_rates: [0.5, 0.05, 0.02, 0.3],
            seed: 1,
        }
    }
}

/// One step's figures.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CompletionStep {
    /// Step index (0 is the initial state).
    pub step: u32,
    /// Mean BCE over receivers.
    pub loss: f64,
    /// IoU of the shadowed pixels (V < 0.5) against the target's.
    pub iou: f64,
}

/// What [`complete_from_shadow`] produced.
pub struct Completion {
    /// The input scene with the optimised Gaussians appended.
    pub scene: Scene,
    /// Index of the first added Gaussian.
    pub first_added: usize,
    /// Visibility before optimisation (the initial Gaussians in place).
    pub before: Vec<f32>,
    /// Visibility after.
    pub after: Vec<f32>,
    /// Visibility of the scene without any added Gaussians.
    pub without: Vec<f32>,
    /// Per-step loss and IoU (the first entry is the initial state).
    pub history: Vec<CompletionStep>,
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
/// missing geometry present). `cameras` are every view: initial Gaussians
/// are placed where none of them sees. `progress` gets every step's figures.
#[allow(clippy::too_many_arguments, reason = "the problem is defined by these independent inputs")]
pub fn complete_from_shadow(
    device: &Device,
    scene: &Scene,
    camera: &Camera,
    cameras: &[Camera],
    sun: &Sun,
    target: &[f32],
    settings: &CompletionSettings,
    progress: &mut dyn FnMut(&CompletionStep),
) -> Result<Completion> {
    let pixels = (camera.width * camera.height) as usize;
    if target.len() != pixels || target.iter().any(|v| !v.is_finite()) {
        return Err(Error::InvalidArgument(format!(
            "the target visibility has {} values (finite?), the {}x{} camera needs {pixels}",
            target.len(),
            camera.width,
            camera.height
        )));
    }
    let st = settings.shadow;
    let mut splatter = Splatter::new(device)?;
    let mut pass = ShadowPass::new(device)?;
    let receiver_settings = SplatSettings {
        channels: Channels { depth: true, median_depth: true, ..Channels::default() },
        ..SplatSettings::default()
    };

    // The scene as given: its receivers and its shadows.
    let gpu = GpuScene::upload(device, scene)?;
    let receivers = splatter.render_frame(&gpu, camera, &receiver_settings)?;
    let host = receivers.gbuffer.read(device)?;
    let bounds = scene.bounds().ok_or_else(|| Error::InvalidArgument("the scene is empty".into()))?;
    let light = light_camera(&bounds, sun, st.resolution, st.fit, Some(camera))?;
    let map = pass.shadow_map_from(&mut splatter, &gpu, light.clone(), sun, &st)?;
    let (v, _) = pass.visibility(&map, &receivers.gbuffer, camera, &st, VisibilityKind::Sigmoid)?;
    let without: Vec<f32> = device.read_buffer(&v)?;
    let mask: Vec<bool> = host.alpha.iter().map(|a| *a >= st.min_alpha).collect();

    // Initial Gaussians: in the box of sun rays from receivers that miss their shadow.
    let img = DepthImage::from_gbuffer(&host);
    let mut lo = DVec3::splat(f64::MAX);
    let mut hi = DVec3::splat(f64::MIN);
    let d = sun.direction.as_dvec3();
    let reach = f64::from((Vec3::from_array(bounds.max) - Vec3::from_array(bounds.min)).length());
    for p in 0..pixels {
        if !mask[p] {
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
        return Err(Error::InvalidArgument("no receiver in view has a surface".into()));
    }
    lo.z = lo.z.max(f64::from(bounds.min[2]));
    hi.z = hi.z.min(f64::from(bounds.max[2]) + 0.5 * reach);
    let mut rng = Pcg64Mcg::seed_from_u64(settings.seed);
    let mut added = Scene { sh_degree: scene.sh_degree, ..Scene::default() };
    let k = sh_coefficients(scene.sh_degree);
    let extent = (hi - lo).max_element();
    let scale = (extent / (settings.gaussians as f64).cbrt()).max(1e-3) as f32;
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
        added.opacity_logits.push(-5.0);
        added.sh.extend(std::iter::repeat_n(0.0, 3 * k));
    }
    if added.means.is_empty() {
        return Err(Error::InvalidArgument("every point of the occluder region is seen by a camera".into()));
    }
    let first_added = scene.len();
    let mut full = scene.clone();
    append(&mut full, &added);
    let gpu = GpuScene::upload(device, &full)?;
    let receiver_frame = receivers;

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
        0..=2 => lrs[0],
        3..=5 => lrs[1],
        6..=9 => lrs[2],
        _ => lrs[3],
    };
    let target_buf = device.upload("shadow target", target)?;
    let mut history = Vec::new();
    let mut before = Vec::new();
    let mut after = Vec::new();
    for step in 0..=settings.steps {
        // Write the added Gaussians' parameters in place.
        let (mut m, mut ls, mut r, mut o) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for chunk in params.chunks(11) {
            m.extend_from_slice(&chunk[0..3]);
            ls.extend_from_slice(&chunk[3..6]);
            r.extend_from_slice(&chunk[6..10]);
            o.push(chunk[10]);
        }
        let at = first_added as u64;
        device.write_buffer(&gpu.means, at * 12, &m)?;
        device.write_buffer(&gpu.log_scales, at * 12, &ls)?;
        device.write_buffer(&gpu.rotations, at * 16, &r)?;
        device.write_buffer(&gpu.opacity_logits, at * 4, &o)?;

        let map = pass.shadow_map_from(&mut splatter, &gpu, light.clone(), sun, &st)?;
        let (v, _) = pass.visibility(&map, &receiver_frame.gbuffer, camera, &st, VisibilityKind::Sigmoid)?;
        let v: Vec<f32> = device.read_buffer(&v)?;
        let b = pass.backward(&map, &receiver_frame.gbuffer, camera, &st, GpuVisibilityLoss::Bce(&target_buf))?;
        let figures = CompletionStep { step, loss: b.loss, iou: shadow_iou(&v, target, &mask) };
        progress(&figures);
        history.push(figures);
        if step == 0 {
            before = v.clone();
        }
        if step == settings.steps {
            after = v;
            break;
        }
        let g_map = splatter.backward(&map.frame, &gpu, &b.map, false)?.read(device)?;
        let mut grads = vec![0.0f32; params.len()];
        for (i, g) in grads.chunks_mut(11).enumerate() {
            let j = first_added + i;
            g[0..3].copy_from_slice(&g_map.means[j]);
            g[3..6].copy_from_slice(&g_map.log_scales[j]);
            g[6..10].copy_from_slice(&g_map.rotations[j]);
            g[10] = g_map.opacity_logits[j];
        }
        adam.step(&mut params, &grads, lr);
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
    let mut completed = scene.clone();
    append(&mut completed, &added);
    Ok(Completion { scene: completed, first_added, before, after, without, history })
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
