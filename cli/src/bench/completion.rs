//! Shadow-guided completion's cost and result on the analytic block
//! ([`srug::scene::blocks::block_completion`]) at several surface spacings
//! (so several scene sizes): the one-time setup (receivers and the scene's
//! own shadows per view), the time per Adam step, the steps until the fit's
//! IoU is within 0.005 of its final value, and the shadow IoU of the
//! completed scene against the ray-cast truth in every camera (views 0, 2
//! and 3 fitted, 1 held out) with the balanced shadow.

use std::time::Instant;

use srug::gpu::Device;
use srug::scene::activate::GpuScene;
use srug::scene::blocks::{block_completion, BlockOptions};
use srug::scene::Bounds;
use srug::shadow::accuracy::shadow_accuracy;
use srug::shadow::completion::{complete_from_views, CompletionProblem, CompletionSettings, ShadowView};
use srug::shadow::{ShadowPass, ShadowSettings, Sun, VisibilityKind};
use srug::splat::Splatter;
use srug::{Error, Result};

/// One spacing's row.
#[derive(Clone, Debug)]
pub struct CompletionRow {
    /// Surface spacing, metres.
    pub spacing: f32,
    /// Gaussians of the incomplete scene.
    pub gaussians: usize,
    /// Gaussians added.
    pub added: usize,
    /// Setup seconds (until the first step's figures).
    pub setup_s: f64,
    /// Seconds per Adam step (mean over the run).
    pub step_ms: f64,
    /// Steps until the fit IoU is within 0.005 of its last value.
    pub converged_at: u32,
    /// Shadow IoU against the truth per camera, before and after.
    pub iou: Vec<(f64, f64)>,
}

fn truth_ious(
    device: &Device,
    scene: &srug::scene::Scene,
    b: &srug::scene::blocks::BlockCompletion,
) -> Result<Vec<f64>> {
    let gpu = GpuScene::upload(device, scene)?;
    let mut splatter = Splatter::new(device)?;
    let pass = ShadowPass::new(device)?;
    let st = ShadowSettings::default();
    let sun = Sun::from_direction(b.sun, [1.0; 3])?;
    let bounds = b.city.scene.bounds().ok_or_else(|| Error::Internal("empty block".into()))?;
    let map = pass
        .shadow_map(&mut splatter, &gpu, &bounds, &sun, &st, None)?
        .ok_or_else(|| Error::Internal("the block's sun is up".into()))?;
    b.cameras
        .iter()
        .map(|c| {
            let (g, _) = splatter.render(&gpu, c, &st.receiver_splat())?;
            let (v, _) = pass.visibility(&map, &g, c, &st, VisibilityKind::Sigmoid)?;
            let v: Vec<f32> = device.read_buffer(&v)?;
            let truth = b.city.true_visibility(c, b.sun);
            Ok(shadow_accuracy(&v, &truth, c.width as usize, c.height as usize).iou())
        })
        .collect()
}

/// Runs the completion at every spacing; `progress` gets a line per stage.
pub fn completion_bench(
    device: &Device,
    spacings: &[f32],
    size: (u32, u32),
    settings: &CompletionSettings,
    mut progress: impl FnMut(&str),
) -> Result<Vec<CompletionRow>> {
    let mut rows = Vec::new();
    for &spacing in spacings {
        progress(&format!("spacing {spacing} m: building the block"));
        let b = block_completion(&BlockOptions { spacing, ..BlockOptions::default() }, size.0, size.1)?;
        let sun = Sun::from_direction(b.sun, [1.0; 3])?;
        let views: Vec<ShadowView> = [0, 2, 3]
            .iter()
            .map(|i| ShadowView { camera: b.cameras[*i].clone(), target: b.city.shadow_target(&b.cameras[*i], b.sun) })
            .collect();
        let sb = b.without.bounds().ok_or_else(|| Error::Internal("empty block".into()))?;
        let region = Bounds { min: sb.min, max: [sb.max[0], sb.max[1], sb.max[2] + 30.0] };
        let problem =
            CompletionProblem { scene: &b.without, region: &region, views: &views, cameras: &b.cameras, sun: &sun };
        progress(&format!("spacing {spacing} m: fitting {} Gaussians' scene", b.without.len()));
        let start = Instant::now();
        let mut first_step = None;
        let c = complete_from_views(device, &problem, settings, &mut |s| {
            if s.step == 0 {
                first_step = Some(start.elapsed().as_secs_f64());
            }
        })?;
        let total = start.elapsed().as_secs_f64();
        let setup_s = first_step.unwrap_or(total);
        let last = c.history.last().map_or(0.0, |s| s.iou);
        let converged_at = c.history.iter().find(|s| s.iou >= last - 0.005).map_or(0, |s| s.step);
        progress(&format!("spacing {spacing} m: measuring against the truth"));
        let before = truth_ious(device, &b.without, &b)?;
        let after = truth_ious(device, &c.scene, &b)?;
        rows.push(CompletionRow {
            spacing,
            gaussians: b.without.len(),
            added: c.added(),
            setup_s,
            step_ms: 1e3 * (total - setup_s) / f64::from(settings.steps.max(1)),
            converged_at,
            iou: before.into_iter().zip(after).collect(),
        });
    }
    Ok(rows)
}

/// The rows as a markdown table.
pub fn completion_markdown(rows: &[CompletionRow], steps: u32) -> String {
    let mut s = String::from(
        "| spacing | Gaussians | added | setup | per step | steps to converge | to converge | shadow IoU vs truth per camera (1 held out), before → after |\n\
         |---:|---:|---:|---:|---:|---:|---:|---|\n",
    );
    for r in rows {
        let ious: Vec<String> = r.iou.iter().map(|(a, b)| format!("{a:.3} → {b:.3}")).collect();
        s += &format!(
            "| {} m | {} | {} | {:.2} s | {:.0} ms | {} of {steps} | {:.1} s | {} |\n",
            r.spacing,
            r.gaussians,
            r.added,
            r.setup_s,
            r.step_ms,
            r.converged_at,
            r.setup_s + r.step_ms * f64::from(r.converged_at) / 1e3,
            ious.join(", ")
        );
    }
    s
}
