//! Shadow-guided completion: Gaussians that no camera sees are optimised so
//! the shadows they cast match target shadows in one or more views (the
//! paper's shadow guidance: shadow masks V' per training view, the sun known).
//!
//! The scene as given casts its own shadows through its shadow map, rendered
//! once per view with [`CompletionSettings::scene_shadow`] (V_scene). The
//! added Gaussians get one shadow map of their own in expected-over-far depth
//! — differentiable even where they are still faint — from one light camera
//! covering every view's receivers, fixed for the run so texels stay put
//! while Gaussians move. Their visibility V_added multiplies (independent
//! occluders): V = V_scene·V_added. Each step takes the visibility loss
//! BCE(V_added, V') over the receivers the scene leaves lit and the target
//! knows, in every view, plus a coverage loss on the map's α (the
//! median-depth map the result is rendered with shadows only under α ≥ 0.5,
//! see [`CompletionSettings::coverage_weight`]), back through the sigmoid
//! test and the added map's splat (the map gradients of the views add up
//! before one splat backward), and moves the Gaussians with Adam. Receivers
//! facing away from the sun do not count: no occluder changes them.
//!
//! Gaussians are spawned along the sun rays of the pixels whose shadow is
//! missing (the target says shadow, V says lit, in most of the pixel's 3×3
//! neighbourhood), between the receiver and where the ray leaves the region,
//! at points no camera sees, and each one's 3σ extent is kept out of every
//! view. Every [`CompletionSettings::refresh_every`] steps, until two thirds
//! of the run, those whose opacity the loss drove below
//! [`CompletionSettings::prune_opacity`] are pruned and new ones spawned
//! along the rays still missing their shadow, up to the count allowed; at the
//! end those that splat nothing (peak α below 1/255) are dropped.
//!
//! The input's Gaussians keep their geometry except those
//! [`CompletionSettings::movable`] selects, which join the added ones; L_Vf
//! ([`CompletionSettings::fixed_steps`]) changes only their fixed-visibility
//! logits, and L_Ve ([`CompletionSettings::editable_from_fixed`]) makes the
//! added Gaussians fit the fixed visibility instead of the targets.
//!
//! Targets are visibilities: 1 lit, 0 shadowed, soft values in between
//! (a detector's probability), negative where unknown (ignored).

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
use crate::splat::backward::BlendGrads;
use crate::splat::{Channels, SplatSettings, Splatter};

/// Knobs of [`complete_from_views`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CompletionSettings {
    /// Adam steps.
    pub steps: u32,
    /// Most Gaussians added at once.
    pub gaussians: usize,
    /// The added Gaussians' shadow test (resolution, k, bias, receivers); its
    /// map depth is always expected-over-far and its light camera covers every view.
    pub shadow: ShadowSettings,
    /// The scene's own shadow map and test (V_scene), rendered once per view
    /// (by default the balanced preset's with centre depths and both coverages
    /// at one half).
    pub scene_shadow: ShadowSettings,
    /// Learning rates: means (in units of the initial Gaussian size), log-scales,
    /// rotations, opacity logits.
    pub learning_rates: [f32; 4],
    /// Initial opacity logit of the added Gaussians.
    pub initial_opacity_logit: f32,
    /// Steps between pruning and respawning (0: never).
    pub refresh_every: u32,
    /// Added Gaussians whose opacity falls below this are pruned at a refresh.
    pub prune_opacity: f32,
    /// Weight of the coverage loss against the visibility loss (see
    /// [`complete_from_views`]): shadows from opaque coverage, as the
    /// median-depth map that renders the result needs.
    pub coverage_weight: f32,
    /// Gaussians of the scene that the fit may move as it moves the added
    /// ones: those whose centre is in this box and that no camera sees
    /// (pruned like them when they fade). `None`: the input's geometry never
    /// changes.
    pub movable: Option<Bounds>,
    /// L_Vf: Adam steps fitting the input scene's fixed visibility (its
    /// `visibility` attribute, the paper's V_f) to the targets before the
    /// added Gaussians grow (0: not fitted). Only those logits change.
    pub fixed_steps: u32,
    /// L_Vf's Adam learning rate on the visibility logits.
    pub fixed_learning_rate: f32,
    /// L_Ve: the added Gaussians' shadows fit the fixed visibility rendered
    /// in each view (after L_Vf when it runs) instead of the targets.
    pub editable_from_fixed: bool,
    /// Seed of the placement.
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
                map_depth: DepthMode::ExpectedOverFar,
                receiver_depth: DepthMode::Expected,
                fit: ShadowFit::SceneBounds,
                // The added Gaussians crowd a few tiles of their map, and the splat
                // backward replays every splat over its whole tile: 8-pixel tiles
                // cut a step by a third (docs/bench/completion.md).
                tile: 8,
                // Centre depths, as measured in docs/bench/completion.md: the added
                // Gaussians start as blobs, whose planes mean nothing yet.
                surface_depth: false,
                ..ShadowSettings::default()
            },
            // One half's coverage for the map and the receivers, not the presets': the
            // fit judged by it moved a building's shadow closer to the truth
            // (docs/bench/completion.md, "Shadow coverages").
            scene_shadow: ShadowSettings {
                surface_depth: false,
                map_coverage: 0.5,
                receiver_coverage: 0.5,
                ..ShadowSettings::default()
            },
            learning_rates: [0.025, 0.025, 0.01, 0.1],
            initial_opacity_logit: -4.0,
            refresh_every: 10,
            prune_opacity: 0.005,
            coverage_weight: 1000.0,
            movable: None,
            fixed_steps: 0,
            fixed_learning_rate: 0.5,
            editable_from_fixed: false,
            seed: 1,
        }
    }
}

impl CompletionSettings {
    /// Checks the values.
    pub fn validate(&self) -> Result<()> {
        self.shadow.validate()?;
        self.scene_shadow.validate()?;
        if self.gaussians == 0 && self.fixed_steps == 0 {
            return Err(Error::invalid("added Gaussians 0", "leaves nothing to fit (without L_Vf steps)"));
        }
        let rates = self.learning_rates.iter().chain([&self.fixed_learning_rate, &self.coverage_weight]);
        if rates.into_iter().any(|r| !r.is_finite() || *r < 0.0) {
            return Err(Error::invalid(
                format!(
                    "learning rates {:?}, fixed-visibility rate {}, coverage weight {}",
                    self.learning_rates, self.fixed_learning_rate, self.coverage_weight
                ),
                "must be finite, ≥ 0",
            ));
        }
        if !self.initial_opacity_logit.is_finite() || !(0.0..1.0).contains(&self.prune_opacity) {
            return Err(Error::invalid(
                format!("initial opacity logit {} / prune opacity {}", self.initial_opacity_logit, self.prune_opacity),
                "need a finite logit and a pruning opacity in [0, 1)",
            ));
        }
        Ok(())
    }
}

/// One view of the fit: a camera and its target visibility.
#[derive(Clone, Debug)]
pub struct ShadowView {
    /// The camera (pinhole or orthographic, no lens distortion).
    pub camera: Camera,
    /// Target sun visibility per pixel, row-major at the camera's size: 1 lit,
    /// 0 shadowed, soft values between; negative where unknown (ignored).
    pub target: Vec<f32>,
}

/// One step's figures.
#[derive(Clone, Debug, PartialEq)]
pub struct CompletionStep {
    /// Which fit: "fixed" (L_Vf, the scene's fixed visibility) or "editable"
    /// (the added Gaussians' shadows).
    pub stage: &'static str,
    /// Step index within the stage (0 is the initial state).
    pub step: u32,
    /// Mean BCE over the receivers the scene leaves lit, summed over the views.
    pub loss: f64,
    /// IoU of the shadowed pixels (V < 0.5) against the target's, over every
    /// known receiver of every view (pooled).
    pub iou: f64,
    /// The same over the receivers the scene alone leaves lit: how well the
    /// missing shadow is recovered (0 for the scene alone).
    pub missing_iou: f64,
    /// Added Gaussians at this step.
    pub gaussians: usize,
    /// The shadow IoU of each view, in the order given.
    pub view_iou: Vec<f64>,
}

/// One view's visibilities.
#[derive(Clone, Debug)]
pub struct ViewCompletion {
    /// Visibility of the scene alone.
    pub without: Vec<f32>,
    /// Visibility with the initial Gaussians.
    pub before: Vec<f32>,
    /// Visibility with the optimised Gaussians.
    pub after: Vec<f32>,
    /// Receivers with a surface that faces the sun and a known target (where
    /// IoU is measured).
    pub mask: Vec<bool>,
    /// The fixed visibility V_f rendered before and after L_Vf (when it ran,
    /// or when the added Gaussians fit it), 1 where no surface.
    pub fixed: Option<(Vec<f32>, Vec<f32>)>,
}

/// What [`complete_from_views`] produced.
pub struct Completion {
    /// The input scene's unmoved Gaussians, then the moved ones, then the added.
    pub scene: Scene,
    /// Index of the first added Gaussian.
    pub first_added: usize,
    /// Gaussians of the input the fit moved (just before the added).
    pub moved: usize,
    /// Per view, in the order given.
    pub views: Vec<ViewCompletion>,
    /// Per-step loss and IoU (the first entry is the initial state).
    pub history: Vec<CompletionStep>,
    /// Added Gaussians whose centre ended inside a camera's view.
    pub visible_added: usize,
}

impl Completion {
    /// Gaussians added.
    pub fn added(&self) -> usize {
        self.scene.len() - self.first_added
    }
}

/// Shadowed-pixel intersection and union of `a` and `b` (V < 0.5) over pixels where `mask`.
fn shadow_overlap(a: &[f32], b: &[f32], mask: &[bool]) -> (usize, usize) {
    let (mut inter, mut union) = (0usize, 0usize);
    for ((x, y), m) in a.iter().zip(b).zip(mask) {
        if *m {
            let (sx, sy) = (*x < 0.5, *y < 0.5);
            inter += usize::from(sx && sy);
            union += usize::from(sx || sy);
        }
    }
    (inter, union)
}

fn ratio((inter, union): (usize, usize)) -> f64 {
    if union == 0 {
        1.0
    } else {
        inter as f64 / union as f64
    }
}

/// IoU of the shadowed sets (V < 0.5) of `a` and `b` over pixels where `mask`.
pub fn shadow_iou(a: &[f32], b: &[f32], mask: &[bool]) -> f64 {
    ratio(shadow_overlap(a, b, mask))
}

/// Adam (β = 0.9, 0.999) over rows of [`ROW`] parameters, rows removable.
struct Adam {
    m: Vec<[f32; ROW]>,
    v: Vec<[f32; ROW]>,
    t: i32,
}

/// Parameters of one added Gaussian: mean, log-scales, rotation, opacity logit.
const ROW: usize = 11;

impl Adam {
    fn step(&mut self, params: &mut [[f32; ROW]], grads: &[[f32; ROW]], lr: impl Fn(usize) -> f32) {
        self.t += 1;
        let (b1, b2) = (0.9f32, 0.999f32);
        let (c1, c2) = (1.0 - b1.powi(self.t), 1.0 - b2.powi(self.t));
        self.m.resize(params.len(), [0.0; ROW]);
        self.v.resize(params.len(), [0.0; ROW]);
        for (((p, g), m), v) in params.iter_mut().zip(grads).zip(&mut self.m).zip(&mut self.v) {
            for i in 0..ROW {
                let g = if g[i].is_finite() { g[i] } else { 0.0 };
                m[i] = b1 * m[i] + (1.0 - b1) * g;
                v[i] = b2 * v[i] + (1.0 - b2) * g * g;
                p[i] -= lr(i) * (m[i] / c1) / ((v[i] / c2).sqrt() + 1e-12);
            }
        }
    }

    /// Keeps the rows where `keep`.
    fn retain(&mut self, keep: &[bool]) {
        let mut k = keep.iter();
        self.m.retain(|_| *k.next().unwrap_or(&false));
        let mut k = keep.iter();
        self.v.retain(|_| *k.next().unwrap_or(&false));
    }
}

/// The ray parameters t ≥ 0 where `o + t·d` is inside the box [lo, hi].
fn ray_in_box(o: DVec3, d: DVec3, lo: DVec3, hi: DVec3) -> Option<(f64, f64)> {
    let (mut t0, mut t1) = (0.0f64, f64::MAX);
    for a in 0..3 {
        if d[a].abs() < 1e-12 {
            if o[a] < lo[a] || o[a] > hi[a] {
                return None;
            }
            continue;
        }
        let (u, v) = ((lo[a] - o[a]) / d[a], (hi[a] - o[a]) / d[a]);
        t0 = t0.max(u.min(v));
        t1 = t1.min(u.max(v));
    }
    (t0 < t1).then_some((t0, t1))
}

/// Where Gaussians may be spawned: the sun rays of receivers whose shadow is
/// missing, inside the region, outside every camera's view.
struct Spawner<'a> {
    rays: Vec<(DVec3, f64, f64)>,
    sun: DVec3,
    cameras: &'a [Camera],
}

impl Spawner<'_> {
    /// Up to `n` points (fewer when the rays are seen everywhere).
    fn points(&self, rng: &mut Pcg64Mcg, n: usize) -> Vec<Vec3> {
        let mut out = Vec::with_capacity(n);
        if self.rays.is_empty() {
            return out;
        }
        for _ in 0..n.saturating_mul(200) {
            if out.len() == n {
                break;
            }
            let (o, t0, t1) = self.rays[rng.random_range(0..self.rays.len())];
            let p = (o + self.sun * rng.random_range(t0..=t1)).as_vec3();
            if !self.cameras.iter().any(|c| c.sees(p)) {
                out.push(p);
            }
        }
        out
    }
}

/// A view's receivers, rendered once from the input scene.
struct Receivers {
    gbuffer: crate::splat::GpuGBuffer,
    depth: DepthImage,
    /// A surface and a known target.
    mask: Vec<bool>,
    without: Vec<f32>,
    /// The target where the added Gaussians answer for it (the scene leaves
    /// the receiver lit), else -1 (ignored by the loss).
    added_target: crate::gpu::Buffer,
    /// Those receivers in the added map: texel, light-space depth, whether the target shadows it.
    coverage: Vec<(usize, f32, bool)>,
}

/// The sun rays, inside `region`, of `view`'s receivers where `select(p)`.
fn receiver_rays(
    view: &ShadowView,
    r: &Receivers,
    st: &ShadowSettings,
    sun: DVec3,
    region: (DVec3, DVec3),
    select: impl Fn(usize) -> bool,
) -> Vec<(DVec3, f64, f64)> {
    (0..r.mask.len())
        .filter(|p| r.mask[*p] && select(*p))
        .filter_map(|p| {
            let z = r.depth.depth(st.receiver_depth, p, f64::from(st.min_alpha), 0.0)?;
            let x = unproject(&view.camera, p, z);
            let (t0, t1) = ray_in_box(x, sun, region.0, region.1)?;
            Some((x, t0, t1))
        })
        .collect()
}

fn add_grads(device: &Device, into: &BlendGrads, from: &BlendGrads) -> Result<()> {
    let pairs = into.channels.iter().filter_map(|(c, b)| from.channels.get(c).map(|f| (b, f)));
    for (a, b) in pairs.chain(into.alpha.iter().zip(from.alpha.iter())) {
        let mut x: Vec<f32> = device.read_buffer(a)?;
        let y: Vec<f32> = device.read_buffer(b)?;
        x.iter_mut().zip(&y).for_each(|(x, y)| *x += y);
        device.write_buffer(a, 0, &x)?;
    }
    Ok(())
}

/// What a completion is asked: the scene, where occluders may be, the views
/// with their targets, every camera, and the sun.
#[derive(Clone, Copy)]
pub struct CompletionProblem<'a> {
    /// The scene as given (never changed).
    pub scene: &'a Scene,
    /// Where occluders may be added: what is missing may lie outside the
    /// scene's bounds (give it room above).
    pub region: &'a Bounds,
    /// The views with targets.
    pub views: &'a [ShadowView],
    /// Every camera of the capture, the views' included: no Gaussian is
    /// spawned or left where one of them sees.
    pub cameras: &'a [Camera],
    /// The sun.
    pub sun: &'a Sun,
}

/// Optimises Gaussians added to the problem's scene so the shadows seen in
/// its views match their targets. `progress` gets every step's figures.
pub fn complete_from_views(
    device: &Device,
    problem: &CompletionProblem<'_>,
    settings: &CompletionSettings,
    progress: &mut dyn FnMut(&CompletionStep),
) -> Result<Completion> {
    let &CompletionProblem { scene, region, views, cameras, sun } = problem;
    settings.validate()?;
    // The movable Gaussians leave the scene and join the added ones.
    let movable: Vec<bool> = match settings.movable {
        Some(b) => scene
            .means
            .iter()
            .map(|p| {
                let v = Vec3::from_array(*p);
                v.cmpge(Vec3::from_array(b.min)).all()
                    && v.cmple(Vec3::from_array(b.max)).all()
                    && !cameras.iter().any(|c| c.sees(v))
            })
            .collect(),
        None => vec![false; scene.len()],
    };
    let moving = scene.select(&movable);
    let unmoved;
    let scene = if moving.is_empty() {
        scene
    } else {
        unmoved = scene.select(&movable.iter().map(|m| !m).collect::<Vec<_>>());
        &unmoved
    };
    if views.is_empty() {
        return Err(Error::invalid("shadow views", "none given: the fit needs at least one view with a target"));
    }
    if !sun.above_horizon() {
        return Err(Error::invalid("sun", "is at or below the horizon: it casts no shadow to fit"));
    }
    for (i, v) in views.iter().enumerate() {
        let pixels = (v.camera.width * v.camera.height) as usize;
        if v.target.len() != pixels || v.target.iter().any(|t| !t.is_finite() || *t > 1.0) {
            return Err(Error::invalid(
                format!("target visibility of view {i} (\"{}\", {} values)", v.camera.name, v.target.len()),
                format!("needs {pixels} finite values ≤ 1 for the {}x{} camera", v.camera.width, v.camera.height),
            ));
        }
        v.camera.require_no_lens("shadow-guided completion")?;
    }
    let (lo, hi) = (DVec3::from_array(region.min.map(f64::from)), DVec3::from_array(region.max.map(f64::from)));
    if !lo.is_finite() || !hi.is_finite() || lo.cmpge(hi).any() {
        return Err(Error::invalid(format!("region {lo}..{hi}"), "is not a box"));
    }
    let scene_bounds = scene.bounds().ok_or_else(|| Error::invalid("scene", "has no Gaussians"))?;
    let st = settings.shadow;
    let added_st = ShadowSettings { map_depth: DepthMode::ExpectedOverFar, fit: ShadowFit::SceneBounds, ..st };
    let sst = settings.scene_shadow;
    let mut splatter = Splatter::new(device)?;
    let mut pass = ShadowPass::new(device)?;
    let (a, b) = (sst.receiver_channels(), added_st.receiver_channels());
    let channels = Channels {
        depth: a.depth || b.depth,
        median_depth: a.median_depth || b.median_depth,
        normal: true,
        ..Channels::default()
    };
    let receiver_settings = SplatSettings { channels, ..sst.receiver_splat() };

    // The scene as given: its receivers and its own shadows, once per view.
    let gpu = GpuScene::upload(device, scene)?;
    let sun_d = sun.direction.as_dvec3();

    // L_Vf, then what the added Gaussians fit: the targets, or (L_Ve) V_f.
    let mut history = Vec::new();
    let mut fixed_fit = None;
    if settings.fixed_steps > 0 || settings.editable_from_fixed {
        let logits = scene.materials.visibility.clone().ok_or_else(|| {
            Error::invalid(
                "scene",
                "has no fixed-visibility attribute (a relightable scene's visibility): the L_Vf and L_Ve losses need it",
            )
        })?;
        let fit = fit_fixed_visibility(device, &mut splatter, &gpu, views, sun, settings, logits, progress)?;
        history.extend(fit.history.iter().cloned());
        fixed_fit = Some(fit);
    }
    let fixed_targets: Vec<ShadowView>;
    let views: &[ShadowView] = match &fixed_fit {
        Some(fit) if settings.editable_from_fixed => {
            fixed_targets = views
                .iter()
                .zip(&fit.after)
                .zip(&fit.surface)
                .map(|((v, f), s)| ShadowView {
                    camera: v.camera.clone(),
                    target: f.iter().zip(s).map(|(f, s)| if *s { *f } else { -1.0 }).collect(),
                })
                .collect();
            &fixed_targets
        }
        _ => views,
    };
    let fixed_views = |i: usize| fixed_fit.as_ref().map(|f| (f.before[i].clone(), f.after[i].clone()));
    let with_fixed = |mut s: Scene| {
        if let Some(f) = fixed_fit.as_ref().filter(|_| settings.fixed_steps > 0) {
            s.materials.visibility = Some(f.logits.clone());
        }
        s
    };
    if settings.gaussians == 0 && moving.is_empty() {
        let out = (0..views.len())
            .map(|i| ViewCompletion {
                without: Vec::new(),
                before: Vec::new(),
                after: Vec::new(),
                mask: fixed_fit.as_ref().map_or_else(Vec::new, |f| f.mask[i].clone()),
                fixed: fixed_views(i),
            })
            .collect();
        return Ok(Completion {
            scene: with_fixed(scene.clone()),
            first_added: scene.len(),
            moved: 0,
            views: out,
            history,
            visible_added: 0,
        });
    }
    let mut receivers = Vec::with_capacity(views.len());
    for view in views {
        let frame = splatter.render_frame(&gpu, &view.camera, &receiver_settings)?;
        let host = frame.gbuffer.read(device)?;
        let map = pass
            .shadow_map(&mut splatter, &gpu, &scene_bounds, sun, &sst, Some(&view.camera))?
            .ok_or_else(|| Error::invalid("sun", "is below the horizon"))?;
        let (v, _) = pass.visibility(&map, &frame.gbuffer, &view.camera, &sst, VisibilityKind::Sigmoid)?;
        let without: Vec<f32> = device.read_buffer(&v)?;
        // Receivers facing away from the sun get no sun light whatever their
        // visibility (a mask calls them shadow): they do not count.
        let facing = |p: usize| {
            host.get(crate::splat::Channel::Normal)
                .is_none_or(|n| Vec3::new(n[3 * p], n[3 * p + 1], n[3 * p + 2]).dot(sun.direction) > 0.0)
        };
        let mask: Vec<bool> = (0..host.alpha.len())
            .map(|p| host.alpha[p] >= st.min_alpha && view.target[p] >= 0.0 && facing(p))
            .collect();
        let added_target: Vec<f32> = view
            .target
            .iter()
            .zip(&without)
            .zip(&mask)
            .map(|((t, w), m)| if *m && *w >= 0.5 { *t } else { -1.0 })
            .collect();
        receivers.push(Receivers {
            gbuffer: frame.gbuffer,
            depth: DepthImage::from_gbuffer(&host),
            mask,
            without,
            added_target: device.upload("shadow target", &added_target)?,
            coverage: Vec::new(),
        });
    }
    if receivers.iter().all(|r| !r.mask.iter().any(|m| *m)) {
        return Err(Error::invalid("receivers", "no view has a surface with a known target"));
    }

    // One light camera over every receiver and the region toward the sun.
    let (mut blo, mut bhi) = (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN));
    for (view, r) in views.iter().zip(&receivers) {
        for p in (0..r.mask.len()).filter(|p| r.mask[*p]) {
            let Some(z) = r.depth.depth(st.receiver_depth, p, f64::from(st.min_alpha), 0.0) else { continue };
            let x = unproject(&view.camera, p, z);
            blo = blo.min(x);
            bhi = bhi.max(x);
            if let Some((_, t1)) = ray_in_box(x, sun_d, lo, hi) {
                blo = blo.min(x + sun_d * t1);
                bhi = bhi.max(x + sun_d * t1);
            }
        }
    }
    if blo.x > bhi.x {
        return Err(Error::invalid("receivers", "none in view has a surface"));
    }
    let light_box = Bounds { min: blo.as_vec3().to_array(), max: bhi.as_vec3().to_array() };
    let light = light_camera(&light_box, sun, st.resolution, ShadowFit::SceneBounds, None)?;
    let texel = f64::from(super::texel_size(&light));
    for (view, r) in views.iter().zip(&mut receivers) {
        for p in 0..r.mask.len() {
            if !r.mask[p] || r.without[p] < 0.5 {
                continue;
            }
            let Some(z) = r.depth.depth(st.receiver_depth, p, f64::from(st.min_alpha), 0.0) else { continue };
            let l = light.world_to_camera(unproject(&view.camera, p, z).as_vec3());
            let px = light.project(l);
            let (tx, ty) = (px.x.floor(), px.y.floor());
            if tx >= 0.0 && ty >= 0.0 && (tx as u32) < light.width && (ty as u32) < light.height {
                let t = ty as usize * light.width as usize + tx as usize;
                r.coverage.push((t, l.z, view.target[p] < 0.5));
            }
        }
    }

    // The missing shadow: rays to spawn along, and the initial size from the
    // light-space footprint of the missing receivers times their ray length.
    let missing = |without: &[f32], i: usize| -> Vec<bool> {
        let raw: Vec<bool> =
            (0..without.len()).map(|p| receivers[i].mask[p] && views[i].target[p] < 0.5 && without[p] >= 0.5).collect();
        majority(&raw, views[i].camera.width as usize)
    };
    let mut spawner = Spawner { rays: Vec::new(), sun: sun_d, cameras };
    for (i, (view, r)) in views.iter().zip(&receivers).enumerate() {
        let m = missing(&r.without, i);
        spawner.rays.extend(receiver_rays(view, r, &st, sun_d, (lo, hi), |p| m[p]));
    }
    if spawner.rays.is_empty() {
        return Err(Error::invalid(
            "targets",
            "mark no shadow missing from the scene inside the region: nothing to complete",
        ));
    }
    let mut footprint = std::collections::HashSet::new();
    let mut length = 0.0;
    for (o, t0, t1) in &spawner.rays {
        let l = light.world_to_camera(o.as_vec3());
        let px = light.project(l);
        footprint.insert((px.x.floor() as i64, px.y.floor() as i64));
        length += t1 - t0;
    }
    let volume = footprint.len() as f64 * texel * texel * length / spawner.rays.len() as f64;
    let scale = (volume / settings.gaussians.max(1) as f64).cbrt().max(texel) as f32;
    let k = sh_coefficients(scene.sh_degree);
    let mut rng = Pcg64Mcg::seed_from_u64(settings.seed);
    let (log_lo, log_hi) = ((1e-2 * scale).ln(), (10.0 * scale).ln());
    let row = |p: Vec3| -> [f32; ROW] {
        let s = scale.ln();
        let mut r = [p.x, p.y, p.z, s, s, s, 1.0, 0.0, 0.0, 0.0, settings.initial_opacity_logit];
        keep_unseen(&mut r, cameras, log_lo);
        r
    };
    // The movable Gaussians first (their scales free within their own range and the
    // added ones'), then the spawned; `origin` says which movable one a row is.
    let mut params: Vec<[f32; ROW]> = (0..moving.len())
        .map(|i| {
            let (m, l, r) = (moving.means[i], moving.log_scales[i], moving.rotations[i]);
            [m[0], m[1], m[2], l[0], l[1], l[2], r[0], r[1], r[2], r[3], moving.opacity_logits[i]]
        })
        .collect();
    let mut origin: Vec<Option<usize>> = (0..moving.len()).map(Some).collect();
    let limits = |o: Option<usize>| match o {
        Some(i) => {
            let l = moving.log_scales[i];
            (l[0].min(l[1]).min(l[2]).min(log_lo), l[0].max(l[1]).max(l[2]).max(log_hi))
        }
        None => (log_lo, log_hi),
    };
    let spawned = spawner.points(&mut rng, settings.gaussians);
    origin.extend(std::iter::repeat_n(None, spawned.len()));
    params.extend(spawned.into_iter().map(row));
    if params.is_empty() {
        return Err(Error::invalid("occluder region", "every point of it is seen by a camera"));
    }
    let to_scene = |params: &[[f32; ROW]]| -> Scene {
        let mut s = Scene { sh_degree: scene.sh_degree, ..Scene::default() };
        for r in params {
            s.means.push([r[0], r[1], r[2]]);
            s.log_scales.push([r[3], r[4], r[5]]);
            s.rotations.push([r[6], r[7], r[8], r[9]]);
            s.opacity_logits.push(r[10]);
        }
        s.sh = vec![0.0; 3 * k * params.len()];
        s
    };
    let mut added_gpu = GpuScene::upload(device, &to_scene(&params))?;
    let mut adam = Adam { m: Vec::new(), v: Vec::new(), t: 0 };
    let lrs = settings.learning_rates;
    let lr = |i: usize| match i {
        0..=2 => lrs[0] * scale,
        3..=5 => lrs[1],
        6..=9 => lrs[2],
        _ => lrs[3],
    };
    let mut out: Vec<ViewCompletion> = receivers
        .iter()
        .enumerate()
        .map(|(i, r)| ViewCompletion {
            without: r.without.clone(),
            before: Vec::new(),
            after: Vec::new(),
            mask: r.mask.clone(),
            fixed: fixed_views(i),
        })
        .collect();
    let refresh_until = settings.steps * 2 / 3;
    for step in 0..=settings.steps {
        if step > 0 && settings.refresh_every > 0 && step % settings.refresh_every == 0 && step <= refresh_until {
            // Prune what the loss faded, respawn along the rays still missing their shadow.
            let keep: Vec<bool> = params.iter().map(|r| sigmoid(r[10]) >= settings.prune_opacity).collect();
            let mut k = keep.iter();
            params.retain(|_| *k.next().unwrap_or(&false));
            let mut k = keep.iter();
            origin.retain(|_| *k.next().unwrap_or(&false));
            adam.retain(&keep);
            let still: Vec<_> = out.iter().map(|o| o.after.clone()).collect();
            spawner.rays.clear();
            for (i, (view, r)) in views.iter().zip(&receivers).enumerate() {
                let m = missing(&still[i], i);
                spawner.rays.extend(receiver_rays(view, r, &st, sun_d, (lo, hi), |p| m[p]));
            }
            let room = settings.gaussians.saturating_sub(origin.iter().filter(|o| o.is_none()).count());
            let spawned = spawner.points(&mut rng, room);
            origin.extend(std::iter::repeat_n(None, spawned.len()));
            params.extend(spawned.into_iter().map(row));
            if params.is_empty() {
                return Err(Error::invalid("shadow fit", "pruned every added Gaussian: the targets ask for no shadow"));
            }
            added_gpu = GpuScene::upload(device, &to_scene(&params))?;
        } else {
            let s = to_scene(&params);
            device.write_buffer(&added_gpu.means, 0, &s.means)?;
            device.write_buffer(&added_gpu.log_scales, 0, &s.log_scales)?;
            device.write_buffer(&added_gpu.rotations, 0, &s.rotations)?;
            device.write_buffer(&added_gpu.opacity_logits, 0, &s.opacity_logits)?;
        }

        let map = pass.shadow_map_from(&mut splatter, &added_gpu, light.clone(), sun, &added_st)?;
        let mut loss = 0.0;
        let (mut all, mut lit) = ((0, 0), (0, 0));
        let mut view_iou = Vec::with_capacity(views.len());
        let mut map_grads: Option<BlendGrads> = None;
        for ((view, r), o) in views.iter().zip(&receivers).zip(&mut out) {
            let (v, _) = pass.visibility(&map, &r.gbuffer, &view.camera, &added_st, VisibilityKind::Sigmoid)?;
            let v_added: Vec<f32> = device.read_buffer(&v)?;
            o.after = v_added.iter().zip(&r.without).map(|(a, b)| a * b).collect();
            let (i, u) = shadow_overlap(&o.after, &view.target, &r.mask);
            all = (all.0 + i, all.1 + u);
            view_iou.push(ratio((i, u)));
            let lit_mask: Vec<bool> = r.mask.iter().zip(&r.without).map(|(m, w)| *m && *w >= 0.5).collect();
            let (i, u) = shadow_overlap(&o.after, &view.target, &lit_mask);
            lit = (lit.0 + i, lit.1 + u);
            if step == 0 {
                o.before = o.after.clone();
            }
            let b =
                pass.backward(&map, &r.gbuffer, &view.camera, &added_st, GpuVisibilityLoss::Bce(&r.added_target))?;
            loss += b.loss;
            match &map_grads {
                None => map_grads = Some(b.map),
                Some(g) => add_grads(device, g, &b.map)?,
            }
        }
        if let (Some(g), true) = (&map_grads, settings.coverage_weight > 0.0) {
            loss += coverage_loss(device, &map, g, &receivers, st.bias, settings.coverage_weight)?;
        }
        let figures = CompletionStep {
            stage: "editable",
            step,
            loss,
            iou: ratio(all),
            missing_iou: ratio(lit),
            gaussians: params.len(),
            view_iou,
        };
        progress(&figures);
        history.push(figures);
        let Some(map_grads) = map_grads.filter(|_| step < settings.steps) else { break };
        let g = splatter.backward(&map.frame, &added_gpu, &map_grads, false)?.read(device)?;
        let grads: Vec<[f32; ROW]> = (0..params.len())
            .map(|i| {
                let mut r = [0.0; ROW];
                r[0..3].copy_from_slice(&g.means[i]);
                r[3..6].copy_from_slice(&g.log_scales[i]);
                r[6..10].copy_from_slice(&g.rotations[i]);
                r[10] = g.opacity_logits[i];
                r
            })
            .collect();
        // Learning rates decay linearly to a tenth over the run.
        let decay = 1.0 - 0.9 * step as f32 / settings.steps.max(1) as f32;
        adam.step(&mut params, &grads, |i| lr(i) * decay);
        for (r, o) in params.iter_mut().zip(&origin) {
            let (lo, hi) = limits(*o);
            for s in &mut r[3..6] {
                *s = s.clamp(lo, hi);
            }
            r[10] = r[10].clamp(-12.0, 12.0);
            keep_unseen(r, cameras, lo);
        }
    }
    // Those that splat nothing go: peak α below 1/255.
    let keep: Vec<bool> = params.iter().map(|r| sigmoid(r[10]) >= 1.0 / 255.0).collect();
    let rows = |moved: bool| -> Vec<[f32; ROW]> {
        params
            .iter()
            .zip(&origin)
            .zip(&keep)
            .filter(|((_, o), k)| **k && o.is_some() == moved)
            .map(|((r, _), _)| *r)
            .collect()
    };
    // The moved keep their colour and materials, with their new geometry.
    let mut kept_moving = vec![false; moving.len()];
    for (o, k) in origin.iter().zip(&keep) {
        if let (Some(i), true) = (o, k) {
            kept_moving[*i] = true;
        }
    }
    let mut moved = moving.select(&kept_moving);
    let geometry = to_scene(&rows(true));
    (moved.means, moved.log_scales, moved.rotations, moved.opacity_logits) =
        (geometry.means, geometry.log_scales, geometry.rotations, geometry.opacity_logits);
    let added = to_scene(&rows(false));
    let visible_added = added.means.iter().filter(|p| cameras.iter().any(|c| c.sees(Vec3::from_array(**p)))).count();
    let mut completed = with_fixed(scene.clone());
    append(&mut completed, &moved);
    let first_added = completed.len();
    append(&mut completed, &added);
    Ok(Completion { scene: completed, first_added, moved: moved.len(), views: out, history, visible_added })
}

/// What L_Vf produced.
struct FixedFit {
    /// V_f per view before and after (1 where no surface).
    before: Vec<Vec<f32>>,
    after: Vec<Vec<f32>>,
    /// Pixels with a surface.
    surface: Vec<Vec<bool>>,
    /// Pixels fitted: a surface facing the sun and a known target.
    mask: Vec<Vec<bool>>,
    /// The fitted visibility logits.
    logits: Vec<f32>,
    history: Vec<CompletionStep>,
}

/// L_Vf: Adam on the scene's fixed-visibility logits so that, in every view,
/// the blended V_f = Σ wᵢ σ(vᵢ) / α matches the target (mean BCE over the
/// pixels with a surface facing the sun and a known target), back through
/// the splat of the visibility channel.
#[allow(clippy::too_many_arguments, reason = "the stage's independent inputs")]
fn fit_fixed_visibility(
    device: &Device,
    splatter: &mut Splatter,
    gpu: &GpuScene,
    views: &[ShadowView],
    sun: &Sun,
    settings: &CompletionSettings,
    mut logits: Vec<f32>,
    progress: &mut dyn FnMut(&CompletionStep),
) -> Result<FixedFit> {
    use crate::splat::{Channel, PerChannel};
    let buffer = gpu.visibility.as_ref().ok_or_else(|| Error::invalid("scene", "has no visibility on the device"))?;
    let min_alpha = settings.shadow.min_alpha;
    let render = SplatSettings {
        channels: Channels { visibility: true, normal: true, ..Channels::default() },
        // The splat backward replays each splat over its whole tile: 8-pixel tiles
        // halve a step (docs/bench/completion.md).
        tile: 8,
        ..SplatSettings::default()
    };
    let (mut m, mut v) = (vec![0.0f32; logits.len()], vec![0.0f32; logits.len()]);
    let mut fit = FixedFit {
        before: Vec::new(),
        after: Vec::new(),
        surface: Vec::new(),
        mask: Vec::new(),
        logits: Vec::new(),
        history: Vec::new(),
    };
    const EPS: f32 = 1e-4;
    for step in 0..=settings.fixed_steps {
        if step > 0 {
            device.write_buffer(buffer, 0, &logits)?;
        }
        let (mut loss, mut all) = (0.0, (0, 0));
        let mut view_iou = Vec::with_capacity(views.len());
        let mut grad = vec![0.0f32; logits.len()];
        fit.after.clear();
        fit.surface.clear();
        fit.mask.clear();
        for view in views {
            let frame = splatter.render_frame(gpu, &view.camera, &render)?;
            let host = frame.gbuffer.read(device)?;
            let (Some(c), Some(normal)) = (host.get(Channel::Visibility), host.get(Channel::Normal)) else {
                return Err(Error::Internal("the fixed-visibility render lacks its channels".into()));
            };
            let n = host.alpha.len();
            let surface: Vec<bool> = host.alpha.iter().map(|a| *a >= min_alpha).collect();
            let facing =
                |p: usize| Vec3::new(normal[3 * p], normal[3 * p + 1], normal[3 * p + 2]).dot(sun.direction) > 0.0;
            let mask: Vec<bool> = (0..n).map(|p| surface[p] && view.target[p] >= 0.0 && facing(p)).collect();
            let vf: Vec<f32> =
                (0..n).map(|p| if surface[p] { (c[p] / host.alpha[p]).clamp(0.0, 1.0) } else { 1.0 }).collect();
            let count = mask.iter().filter(|m| **m).count().max(1) as f64;
            let mut d_c = vec![0.0f32; n];
            for p in (0..n).filter(|p| mask[*p]) {
                let (x, t) = (vf[p].clamp(EPS, 1.0 - EPS), view.target[p]);
                loss -= (f64::from(t) * f64::from(x.ln()) + f64::from(1.0 - t) * f64::from((1.0 - x).ln())) / count;
                d_c[p] = ((x - t) / (x * (1.0 - x)) / count as f32) / host.alpha[p];
            }
            let (i, u) = shadow_overlap(&vf, &view.target, &mask);
            all = (all.0 + i, all.1 + u);
            view_iou.push(ratio((i, u)));
            if step < settings.fixed_steps {
                let d = device.upload("dL/dV_f", &d_c)?;
                let grads = BlendGrads {
                    channels: PerChannel::default().with(Channel::Visibility, d),
                    ..BlendGrads::default()
                };
                let g = splatter.backward(&frame, gpu, &grads, true)?.read(device)?;
                let values = g.values.ok_or_else(|| Error::Internal("no value gradients".into()))?;
                for ((gi, val), l) in grad.iter_mut().zip(&values).zip(&logits) {
                    let s = sigmoid(*l);
                    *gi += val[13] * s * (1.0 - s);
                }
            }
            fit.after.push(vf);
            fit.surface.push(surface);
            fit.mask.push(mask);
        }
        if step == 0 {
            fit.before = fit.after.clone();
        }
        let figures =
            CompletionStep { stage: "fixed", step, loss, iou: ratio(all), missing_iou: 0.0, gaussians: 0, view_iou };
        progress(&figures);
        fit.history.push(figures);
        if step == settings.fixed_steps {
            break;
        }
        // Adam (β = 0.9, 0.999), the learning rate decaying to a tenth.
        let t = (step + 1) as i32;
        let lr = settings.fixed_learning_rate * (1.0 - 0.9 * step as f32 / settings.fixed_steps as f32);
        let (c1, c2) = (1.0 - 0.9f32.powi(t), 1.0 - 0.999f32.powi(t));
        for (((l, g), m), v) in logits.iter_mut().zip(&grad).zip(&mut m).zip(&mut v) {
            *m = 0.9 * *m + 0.1 * g;
            *v = 0.999 * *v + 0.001 * g * g;
            *l = (*l - lr * (*m / c1) / ((*v / c2).sqrt() + 1e-12)).clamp(-12.0, 12.0);
        }
    }
    fit.logits = logits;
    Ok(fit)
}

/// The coverage loss: a receiver the target shadows wants the added map's
/// texel covered (−ln α); one the target leaves lit wants it uncovered
/// (−ln(1 − α)) where the added Gaussians' mean depth there is in front of
/// it. The expected-over-far test alone lets faint clouds cast shadows that
/// a median-depth map (which needs α ≥ 0.5) would not, and lets half-opaque
/// ones hide shadows it would cast. Adds dL/dα into `grads`; returns the loss.
fn coverage_loss(
    device: &Device,
    map: &super::ShadowMap,
    grads: &BlendGrads,
    receivers: &[Receivers],
    bias: f32,
    weight: f32,
) -> Result<f64> {
    let Some(alpha_grad) = &grads.alpha else { return Ok(0.0) };
    let alpha: Vec<f32> = device.read_buffer(&map.frame.gbuffer.alpha)?;
    let depth_sum: Vec<f32> = match map.frame.gbuffer.get(crate::splat::Channel::Depth) {
        Some(b) => device.read_buffer(b)?,
        None => return Ok(0.0),
    };
    let mut d_alpha: Vec<f32> = device.read_buffer(alpha_grad)?;
    let count: usize = receivers.iter().map(|r| r.coverage.len()).sum();
    let scale = f64::from(weight) / count.max(1) as f64;
    let mut loss = 0.0;
    const EPS: f32 = 1e-4;
    for &(t, z, shadowed) in receivers.iter().flat_map(|r| &r.coverage) {
        let a = alpha[t].clamp(EPS, 1.0 - EPS);
        if shadowed {
            loss -= f64::from(a.ln()) * scale;
            d_alpha[t] -= (scale / f64::from(a)) as f32;
        } else if alpha[t] > EPS && depth_sum[t] / alpha[t] < z - bias {
            loss -= f64::from((1.0 - a).ln()) * scale;
            d_alpha[t] += (scale / f64::from(1.0 - a)) as f32;
        }
    }
    device.write_buffer(alpha_grad, 0, &d_alpha)?;
    Ok(loss)
}

/// The pixels set in most of their 3×3 neighbourhood (5 of 9): isolated
/// pixels of a noisy mask seed no occluder.
fn majority(set: &[bool], width: usize) -> Vec<bool> {
    let height = set.len() / width.max(1);
    (0..set.len())
        .map(|p| {
            let (x, y) = (p % width, p / width);
            let mut n = 0;
            for yy in y.saturating_sub(1)..(y + 2).min(height) {
                for xx in x.saturating_sub(1)..(x + 2).min(width) {
                    n += usize::from(set[yy * width + xx]);
                }
            }
            set[p] && n >= 5
        })
        .collect()
}

/// Whether a ball of radius `radius` at `p` reaches into a camera's view
/// (sampled: the centre, its 14 axis and diagonal extremes, the point nearest each camera).
fn seen(cameras: &[Camera], p: Vec3, radius: f32) -> bool {
    const DIRECTIONS: [[f32; 3]; 14] = [
        [1.0, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, -1.0],
        [1.0, 1.0, 1.0],
        [1.0, 1.0, -1.0],
        [1.0, -1.0, 1.0],
        [1.0, -1.0, -1.0],
        [-1.0, 1.0, 1.0],
        [-1.0, 1.0, -1.0],
        [-1.0, -1.0, 1.0],
        [-1.0, -1.0, -1.0],
    ];
    cameras.iter().any(|c| {
        let toward = (c.position - p).normalize_or_zero();
        c.sees(p)
            || c.sees(p + toward * radius)
            || DIRECTIONS.iter().any(|d| c.sees(p + Vec3::from_array(*d).normalize() * radius))
    })
}

/// Keeps an added Gaussian out of every view, so the input views do not
/// change: its 3σ extent shrinks until no camera sees it; one whose centre a
/// camera sees is faded to nothing (pruned at the end).
fn keep_unseen(r: &mut [f32; ROW], cameras: &[Camera], log_lo: f32) {
    let p = Vec3::new(r[0], r[1], r[2]);
    if cameras.iter().any(|c| c.sees(p)) {
        r[10] = -12.0;
        return;
    }
    let largest = |r: &[f32; ROW]| r[3].max(r[4]).max(r[5]);
    while largest(r) > log_lo && seen(cameras, p, 3.0 * largest(r).exp()) {
        for s in &mut r[3..6] {
            *s = (*s - 0.2).max(log_lo);
        }
    }
}

fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}

/// Appends `b`'s Gaussians to `a`: `a`'s optional attributes take `b`'s
/// where it has them, neutral values where not (both share an SH degree).
fn append(a: &mut Scene, b: &Scene) {
    let n = b.means.len();
    a.means.extend(&b.means);
    a.log_scales.extend(&b.log_scales);
    a.rotations.extend(&b.rotations);
    a.opacity_logits.extend(&b.opacity_logits);
    a.sh.extend(&b.sh);
    fn extend<T: Copy>(to: &mut Option<Vec<T>>, from: &Option<Vec<T>>, n: usize, zero: T) {
        if let Some(v) = to {
            match from {
                Some(f) => v.extend(f),
                None => v.extend(std::iter::repeat_n(zero, n)),
            }
        }
    }
    extend(&mut a.normals, &b.normals, n, [0.0; 3]);
    let (m, f) = (&mut a.materials, &b.materials);
    extend(&mut m.albedo, &f.albedo, n, [0.0; 3]);
    extend(&mut m.roughness, &f.roughness, n, 0.0);
    extend(&mut m.metallic, &f.metallic, n, 0.0);
    extend(&mut m.ao, &f.ao, n, 0.0);
    extend(&mut m.visibility, &f.visibility, n, 0.0);
}

/// The demo's completion problem: the demo city without the Gaussians of its
/// off-screen tower (those within half a metre of its box).
pub fn without_offscreen_tower(demo: &crate::scene::demo::DemoCity) -> Scene {
    demo.scene.without_box(&demo.offscreen_tower, 0.5)
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
    let st = options.settings.scene_shadow;
    // The target: the full scene's shadow, from the light camera the completion will use.
    let mut splatter = Splatter::new(device)?;
    let pass = ShadowPass::new(device)?;
    let full = GpuScene::upload(device, &demo.scene)?;
    let channels = Channels { depth: true, median_depth: true, normal: true, ..Channels::default() };
    let splat = SplatSettings { channels, ..st.receiver_splat() };
    let receivers = splatter.render_frame(&full, &camera, &splat)?;
    // Occluders may be anywhere in the city's extent (the tower included: what is
    // removed is unknown to the fit, the extent of the place is not).
    let bounds = demo.scene.bounds().ok_or_else(|| Error::invalid("demo scene", "is empty"))?;
    let light = light_camera(&bounds, &sun, st.resolution, st.fit, Some(&camera))?;
    let map = pass.shadow_map_from(&mut splatter, &full, light, &sun, &st)?;
    let (v, _) = pass.visibility(&map, &receivers.gbuffer, &camera, &st, VisibilityKind::Sigmoid)?;
    let target: Vec<f32> = device.read_buffer(&v)?;
    // The region: the city's extent, with room above for what is missing.
    let diagonal = (Vec3::from_array(bounds.max) - Vec3::from_array(bounds.min)).length();
    let region = Bounds { min: bounds.min, max: [bounds.max[0], bounds.max[1], bounds.max[2] + 0.5 * diagonal] };
    let views = [ShadowView { camera: camera.clone(), target: target.clone() }];
    let mut cameras = demo.cameras.clone();
    cameras.push(camera.clone());
    let problem = CompletionProblem { scene: &without, region: &region, views: &views, cameras: &cameras, sun: &sun };
    let completion = complete_from_views(device, &problem, &options.settings, progress)?;
    Ok(DemoCompletionResult { camera, target, removed: demo.scene.len() - without.len(), completion })
}
