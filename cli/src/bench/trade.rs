//! `srug bench trade`: the speed/accuracy trade of the quality knobs.
//!
//! One relit frame of the demo city (SH degree 3, materials, sun and
//! procedural sky) per setting. Each knob is varied alone from the balanced
//! preset — shadow-map resolution, k, receiver and map depth modes, sigmoid
//! against traced visibility, SH degree used, render scale, U-Net storage
//! precision — and the three presets are measured as they are. For each
//! setting: GPU frame time over the repeats (median, min, max; per-stage-group
//! medians), the display image's PSNR and SSIM against the reference preset's
//! image, and the shadow's IoU and mean |ΔV| against traced visibility from a
//! 4096 map (receivers with a surface in the full-size frame).
//!
//! Frames rendered at a lower render scale are upsampled bilinearly on the
//! host before they are compared; that upsampling is not in the frame time.
//! The traced shadow test (and any visibility) at a lower scale is upsampled
//! the same way before its IoU is taken.

use super::median;
use srug::error::{Error, Result};
use srug::frame::block_accuracy::block_shadow_accuracy;
use srug::frame::{Preset, RelightSettings, Relighter};
use srug::gpu::Device;
use srug::indirect::{StoragePrecision, UNet, UNetWeights};
use srug::metrics::{psnr, ssim, RgbImage};
use srug::scene::activate::GpuScene;
use srug::scene::blocks::{block_city, BlockOptions, BlockSplats};
use srug::scene::demo::{demo_city, DemoOptions};
use srug::shade::{BrdfLut, EnvironmentPrep, PrepareSettings, ProceduralSky};
use srug::shadow::accuracy::ShadowAccuracy;
use srug::shadow::completion::shadow_iou;
use srug::shadow::{DepthMode, ShadowFilter, ShadowFit, ShadowPass, Sun, VisibilityKind};

/// One setting to measure.
#[derive(Clone, Debug, PartialEq)]
pub struct TradeSetting {
    /// The knob varied (`preset` for the presets).
    pub knob: &'static str,
    /// The knob's value.
    pub value: String,
    /// The relighting settings.
    pub settings: RelightSettings,
    /// Activation storage of the network (when there is one).
    pub precision: StoragePrecision,
}

/// The settings `srug bench trade` measures: the presets, then each knob
/// varied alone from the balanced preset (values equal to balanced skipped).
pub fn trade_settings(with_network: bool) -> Vec<TradeSetting> {
    let base = RelightSettings::preset(Preset::Balanced);
    let mut out: Vec<TradeSetting> = Preset::ALL
        .iter()
        .map(|p| TradeSetting {
            knob: "preset",
            value: p.name().into(),
            settings: RelightSettings::preset(*p),
            precision: p.indirect_precision(),
        })
        .collect();
    let mut knob = |knob: &'static str, value: String, edit: &dyn Fn(&mut RelightSettings)| {
        let mut settings = base;
        edit(&mut settings);
        if settings != base {
            out.push(TradeSetting { knob, value, settings, precision: StoragePrecision::Fp32 });
        }
    };
    for r in [256, 512, 1024, 4096] {
        knob("shadow resolution", r.to_string(), &|s| s.shadow.resolution = r);
    }
    for k in [5.0f32, 20.0, 200.0, 1000.0] {
        knob("k", k.to_string(), &|s| s.shadow.k = k);
    }
    knob("receiver depth", "expected".into(), &|s| s.shadow.receiver_depth = DepthMode::Expected);
    knob("map depth", "expected".into(), &|s| s.shadow.map_depth = DepthMode::Expected);
    knob("shadow test", "traced".into(), &|s| s.visibility_kind = VisibilityKind::Traced);
    knob("shadow filter", "depth".into(), &|s| s.shadow.filter = ShadowFilter::Depth);
    knob("surface depths", "off".into(), &|s| s.shadow.surface_depth = false);
    knob("surface depths", "map too".into(), &|s| s.shadow.map_surface_depth = true);
    for c in [0.5f32, 0.55, 0.65] {
        knob("shadow map coverage", c.to_string(), &|s| s.shadow.map_coverage = c);
    }
    for c in [0.35f32, 0.4, 0.5] {
        knob("shadow receiver coverage", c.to_string(), &|s| s.shadow.receiver_coverage = c);
    }
    knob("shadow fit", "view".into(), &|s| s.shadow.fit = ShadowFit::ViewFrustum);
    for n in [2u32, 3] {
        knob("shadow fit", format!("{n} cascades"), &|s| {
            s.shadow.fit = ShadowFit::Cascades;
            s.shadow.cascades = n;
        });
    }
    for d in [0u32, 1, 2] {
        knob("SH degree", d.to_string(), &|s| s.sh_degree = Some(d));
    }
    for r in [0.25f32, 0.5, 0.75] {
        knob("render scale", r.to_string(), &|s| s.render_scale = r);
    }
    for t in [8u32, 32] {
        knob("tile size", t.to_string(), &|s| {
            s.tile = t;
            s.shadow.tile = t;
        });
    }
    if with_network {
        out.push(TradeSetting {
            knob: "U-Net storage",
            value: "fp16".into(),
            settings: base,
            precision: StoragePrecision::Fp16,
        });
    }
    out
}

/// What the trade benchmark renders.
#[derive(Clone, Debug)]
pub struct TradeSetup {
    /// Gaussians in the demo city.
    pub gaussians: usize,
    /// Output size.
    pub size: (u32, u32),
    /// Sun azimuth and elevation, degrees.
    pub sun: (f32, f32),
    /// Frames per setting.
    pub repeats: usize,
    /// Indirect-light network weights; without them no inference runs.
    pub network: Option<UNetWeights>,
}

/// One measured setting.
#[derive(Clone, Debug)]
pub struct TradeRow {
    /// The setting.
    pub setting: TradeSetting,
    /// Frame GPU seconds: median, min, max over the repeats.
    pub seconds: [f64; 3],
    /// Median seconds per stage group (splat, shadow map, shadow test, shading, indirect).
    pub groups: Vec<(&'static str, f64)>,
    /// PSNR (dB) of the display image against the reference preset's (+∞ when equal).
    pub psnr: f64,
    /// SSIM against the reference preset's image.
    pub ssim: f64,
    /// PSNR of the plain 3DGS colour (the G-buffer's rgb, which the relit
    /// image does not use) against the reference's: where the SH degree shows.
    pub colour_psnr: f64,
    /// IoU of the shadowed receivers (V < 0.5) against traced visibility (None: no shadow pass).
    pub shadow_iou: Option<f64>,
    /// Mean |V − V_traced| over receivers with a surface.
    pub shadow_mean_abs_diff: Option<f64>,
    /// The setting's shadows against the ray-cast truth of the analytic block
    /// (rough splats, three suns, three street cameras).
    pub block: ShadowAccuracy,
    /// Whether no other row is both faster (median) and more accurate (PSNR).
    pub pareto: bool,
}

/// The stage group of a stage name.
pub fn stage_group(name: &str) -> &'static str {
    if name.starts_with("shadow map") {
        "shadow map"
    } else if name.contains("shadow") || name.contains("visibility") {
        "shadow test"
    } else if name.starts_with("shade") {
        "shading"
    } else if srug::splat::SPLAT_STAGES.contains(&name) {
        "splat"
    } else {
        "indirect"
    }
}

/// The stage groups in pipeline order.
pub const STAGE_GROUPS: [&str; 5] = ["splat", "shadow map", "shadow test", "shading", "indirect"];

/// Seconds per stage group of one frame, in [`STAGE_GROUPS`] order.
pub fn group_seconds(timings: &srug::gpu::Timings) -> [f64; 5] {
    let mut out = [0.0; 5];
    for s in &timings.stages {
        if let Some(i) = STAGE_GROUPS.iter().position(|g| *g == stage_group(&s.name)) {
            out[i] += s.seconds;
        }
    }
    out
}

struct Measured {
    seconds: Vec<f64>,
    groups: Vec<Vec<f64>>,
    display: RgbImage,
    colour: RgbImage,
    visibility: Option<Vec<f32>>,
    alpha: Vec<f32>,
}

/// Runs every setting of [`trade_settings`]; the reference preset first,
/// since every error is measured against it.
pub fn trade_bench(device: &Device, setup: &TradeSetup, mut progress: impl FnMut(&str)) -> Result<Vec<TradeRow>> {
    let (width, height) = setup.size;
    progress("generating the demo city");
    let city = demo_city(&DemoOptions { seed: 7, gaussians: setup.gaussians, sh_degree: 3 })?;
    let gpu = GpuScene::upload(device, &city.scene)?;
    let attributes = city.scene.attributes();
    let bounds = city.scene.bounds().ok_or_else(|| Error::invalid("demo city", "is empty"))?;
    let camera = city.cameras[0].resized(width, height);
    let sun = Sun::from_azimuth_elevation(setup.sun.0, setup.sun.1, [std::f32::consts::PI; 3])?;
    progress("preparing the sky");
    let prep = EnvironmentPrep::new(device)?;
    let brdf = prep.brdf_table(BrdfLut::Karis, 129, 1024)?;
    let sky = ProceduralSky::new(sun.direction, sun.intensity[0]).render()?;
    let env = prep.prepare(&sky, &PrepareSettings::default())?;
    let mut relighter = Relighter::new(device)?;
    let mut networks = Vec::new();
    if let Some(w) = &setup.network {
        for p in [StoragePrecision::Fp32, StoragePrecision::Fp16] {
            if p == StoragePrecision::Fp16 && !device.info().storage_16bit {
                continue;
            }
            networks.push((p, Some(UNet::with_precision(device, w, p)?)));
        }
    }
    let mut settings = trade_settings(setup.network.is_some());
    if !device.info().storage_16bit {
        settings.retain(|s| s.knob != "U-Net storage");
    }
    let reference = RelightSettings::preset(Preset::Reference);
    // Every setting's shadows against the analytic block's truth.
    let block = block_city(&BlockOptions { splats: BlockSplats::Rough, ..BlockOptions::default() })?;
    let block_gpu = GpuScene::upload(device, &block.scene)?;
    let mut block_splatter = srug::splat::Splatter::new(device)?;
    let block_pass = ShadowPass::new(device)?;
    let mut block_accuracies = Vec::with_capacity(settings.len());
    for setting in &settings {
        progress(&format!("{} {}: the analytic block", setting.knob, setting.value));
        let (splatter, pass) = (&mut block_splatter, &block_pass);
        let per_sun = block_shadow_accuracy(
            device,
            splatter,
            pass,
            &block,
            &block_gpu,
            &setting.settings,
            None,
            &mut |_| Ok(()),
        )?;
        let mut accuracy = ShadowAccuracy::default();
        per_sun.iter().for_each(|(_, a)| accuracy.add(a));
        block_accuracies.push(accuracy);
    }

    let mut measure = |setting: &TradeSetting, label: &str| -> Result<Measured> {
        // The setting's precision, or fp32 where the device cannot store fp16.
        let slot = match networks.iter().position(|(p, _)| *p == setting.precision) {
            Some(i) => networks.get_mut(i),
            None => networks.first_mut(),
        };
        if let Some((_, net)) = slot {
            relighter.set_network(net.take());
        }
        let mut m = Measured {
            seconds: Vec::new(),
            groups: vec![Vec::new(); 5],
            display: empty(),
            colour: empty(),
            visibility: None,
            alpha: Vec::new(),
        };
        // Timed as a relit frame runs (the settings' own rgb: off in every preset).
        for r in 0..setup.repeats.max(1) {
            progress(&format!("{label} ({}/{})", r + 1, setup.repeats.max(1)));
            let relit =
                relighter.render(&gpu, &attributes, &bounds, &camera, Some(&sun), &env, &brdf, &setting.settings)?;
            m.seconds.push(relit.timings.total_seconds());
            for (i, t) in group_seconds(&relit.timings).into_iter().enumerate() {
                m.groups[i].push(t);
            }
            if r == 0 {
                let image = relit.shaded.read(device)?.resampled(width, height)?;
                m.display = RgbImage { width, height, rgb: image.display };
                let size = (relit.shaded.width, relit.shaded.height);
                let full = |v: &[f32]| srug::image::resample_bilinear(v, size, 1, (width, height));
                if let Some(v) = &relit.visibility {
                    m.visibility = Some(full(&device.read_buffer(v)?)?);
                }
                m.alpha = full(&device.read_buffer(&relit.gbuffer.alpha)?)?;
            }
        }
        // The splatted colour for the colour PSNR column: one more frame, untimed.
        progress(&format!("{label} (colour)"));
        let settings = RelightSettings { rgb: true, ..setting.settings };
        let relit = relighter.render(&gpu, &attributes, &bounds, &camera, Some(&sun), &env, &brdf, &settings)?;
        let size = (relit.shaded.width, relit.shaded.height);
        let rgb: Vec<f32> = device.read_buffer(relit.gbuffer.rgb_buffer()?)?;
        m.colour = RgbImage { width, height, rgb: srug::image::resample_bilinear(&rgb, size, 3, (width, height))? };
        if let Some(net) = relighter.take_network() {
            if let Some((_, slot)) = networks.iter_mut().find(|(p, _)| *p == net.precision()) {
                *slot = Some(net);
            }
        }
        Ok(m)
    };

    let reference_setting = TradeSetting {
        knob: "preset",
        value: "reference".into(),
        settings: reference,
        precision: StoragePrecision::Fp32,
    };
    let truth = measure(&reference_setting, "reference")?;
    let traced = truth.visibility.clone();
    // Receivers with a surface in the full-size reference frame.
    let mask: Vec<bool> = truth.alpha.iter().map(|a| *a >= reference.shadow.min_alpha).collect();
    let covered = mask.iter().filter(|m| **m).count().max(1);

    let mut rows = Vec::new();
    for (setting, block_accuracy) in settings.into_iter().zip(block_accuracies) {
        let label = format!("{} {}", setting.knob, setting.value);
        let m = if setting == reference_setting { None } else { Some(measure(&setting, &label)?) };
        let m = m.as_ref().unwrap_or(&truth);
        let (shadow_iou_v, mad) = match (&m.visibility, &traced) {
            (Some(v), Some(t)) => {
                let diff: f64 =
                    v.iter().zip(t).zip(&mask).filter(|(_, m)| **m).map(|((a, b), _)| f64::from((a - b).abs())).sum();
                (Some(shadow_iou(v, t, &mask)), Some(diff / covered as f64))
            }
            _ => (None, None),
        };
        let mut sorted = m.seconds.clone();
        sorted.sort_by(f64::total_cmp);
        rows.push(TradeRow {
            seconds: [median(m.seconds.clone()), sorted[0], sorted[sorted.len() - 1]],
            groups: STAGE_GROUPS.iter().zip(&m.groups).map(|(g, v)| (*g, median(v.clone()))).collect(),
            psnr: psnr(&m.display, &truth.display, 1.0)?,
            ssim: ssim(&m.display, &truth.display, 1.0)?,
            colour_psnr: psnr(&m.colour, &truth.colour, 1.0)?,
            shadow_iou: shadow_iou_v,
            shadow_mean_abs_diff: mad,
            block: block_accuracy,
            pareto: false,
            setting,
        });
    }
    mark_pareto(&mut rows);
    Ok(rows)
}

fn empty() -> RgbImage {
    RgbImage { width: 0, height: 0, rgb: Vec::new() }
}

/// Marks the rows no other row dominates (at least as fast and as accurate, better in one).
pub fn mark_pareto(rows: &mut [TradeRow]) {
    let points: Vec<(f64, f64)> = rows.iter().map(|r| (r.seconds[0], r.psnr)).collect();
    for (i, r) in rows.iter_mut().enumerate() {
        let (t, q) = points[i];
        r.pareto = !points.iter().enumerate().any(|(j, &(tj, qj))| j != i && tj <= t && qj >= q && (tj < t || qj > q));
    }
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map_or_else(|| "–".into(), |v| format!("{v:.digits$}"))
}

fn db(v: f64) -> String {
    if v.is_infinite() {
        "∞".into()
    } else {
        format!("{v:.2}")
    }
}

/// The rows as CSV (seconds in milliseconds; `inf` PSNR for the reference).
pub fn trade_csv(rows: &[TradeRow]) -> String {
    let mut s = String::from("knob,value,median_ms,min_ms,max_ms");
    for g in STAGE_GROUPS {
        s += &format!(",{}_ms", g.replace(' ', "_"));
    }
    s += ",psnr_db,ssim,colour_psnr_db,shadow_iou,shadow_mean_abs_dv,block_iou,block_false_shadow,block_light_leak,\
          block_edge_px,pareto\n";
    for r in rows {
        s += &format!(
            "{},{},{:.3},{:.3},{:.3}",
            r.setting.knob,
            r.setting.value,
            r.seconds[0] * 1e3,
            r.seconds[1] * 1e3,
            r.seconds[2] * 1e3
        );
        for (_, t) in &r.groups {
            s += &format!(",{:.3}", t * 1e3);
        }
        let csv_db = |v: f64| if v.is_infinite() { "inf".into() } else { format!("{v:.3}") };
        let b = &r.block;
        s += &format!(
            ",{},{:.5},{},{},{},{:.4},{:.5},{:.5},{:.3},{}\n",
            csv_db(r.psnr),
            r.ssim,
            csv_db(r.colour_psnr),
            opt(r.shadow_iou, 4).replace('–', ""),
            opt(r.shadow_mean_abs_diff, 4).replace('–', ""),
            b.iou(),
            b.false_shadow_rate(),
            b.light_leak_rate(),
            b.edge_error(),
            r.pareto
        );
    }
    s
}

/// The rows as a markdown table.
pub fn trade_markdown(rows: &[TradeRow]) -> String {
    let mut s = String::from(
        "| knob | value | frame ms (median [min, max]) | splat | shadow map | shadow test | shading | indirect \
         | PSNR dB | SSIM | colour PSNR dB | shadow IoU | mean abs dV | block IoU | block false shadow | block leak \
         | block edge px | Pareto |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        s += &format!(
            "| {} | {} | {:.1} [{:.1}, {:.1}] |",
            r.setting.knob,
            r.setting.value,
            r.seconds[0] * 1e3,
            r.seconds[1] * 1e3,
            r.seconds[2] * 1e3
        );
        for (_, t) in &r.groups {
            s += &format!(" {:.1} |", t * 1e3);
        }
        let b = &r.block;
        s += &format!(
            " {} | {:.4} | {} | {} | {} | {:.3} | {:.2}% | {:.2}% | {:.2} | {} |\n",
            db(r.psnr),
            r.ssim,
            db(r.colour_psnr),
            opt(r.shadow_iou, 3),
            opt(r.shadow_mean_abs_diff, 4),
            b.iou(),
            100.0 * b.false_shadow_rate(),
            100.0 * b.light_leak_rate(),
            b.edge_error(),
            if r.pareto { "yes" } else { "" }
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(ms: f64, psnr: f64) -> TradeRow {
        TradeRow {
            setting: trade_settings(false).remove(0),
            seconds: [ms * 1e-3; 3],
            groups: Vec::new(),
            psnr,
            ssim: 1.0,
            colour_psnr: psnr,
            shadow_iou: None,
            shadow_mean_abs_diff: None,
            block: ShadowAccuracy::default(),
            pareto: false,
        }
    }

    #[test]
    fn pareto_front_keeps_only_undominated_rows() {
        let mut rows =
            vec![row(10.0, 30.0), row(20.0, 40.0), row(25.0, 35.0), row(30.0, f64::INFINITY), row(10.0, 25.0)];
        mark_pareto(&mut rows);
        let front: Vec<bool> = rows.iter().map(|r| r.pareto).collect();
        assert_eq!(front, [true, true, false, true, false]);
    }

    #[test]
    fn settings_vary_one_knob_from_balanced_and_skip_duplicates() {
        let balanced = RelightSettings::preset(Preset::Balanced);
        let all = trade_settings(true);
        assert_eq!(all.iter().filter(|s| s.knob == "preset").count(), 3);
        assert!(all.iter().any(|s| s.knob == "U-Net storage"));
        assert_eq!(all.iter().filter(|s| s.knob == "tile size").map(|s| s.settings.tile).collect::<Vec<_>>(), [8, 32]);
        assert!(!trade_settings(false).iter().any(|s| s.knob == "U-Net storage"));
        for s in all.iter().filter(|s| s.knob != "preset" && s.knob != "U-Net storage") {
            assert_ne!(s.settings, balanced, "{} {} repeats balanced", s.knob, s.value);
        }
        assert_eq!(stage_group("shadow map blend"), "shadow map");
        assert_eq!(stage_group("sigmoid shadow test"), "shadow test");
        assert_eq!(stage_group("traced visibility"), "shadow test");
        assert_eq!(stage_group("shade lights"), "shading");
        assert_eq!(stage_group("blend"), "splat");
        assert_eq!(stage_group("cull"), "splat", "compacted records' first pass");
        assert_eq!(stage_group("down1"), "indirect");
        let stage = |name: &str, seconds| srug::gpu::StageTime { name: name.into(), seconds };
        let timings = srug::gpu::Timings {
            stages: vec![stage("blend", 1.0), stage("shadow map blend", 2.0), stage("sort", 0.5), stage("inc", 4.0)],
        };
        assert_eq!(group_seconds(&timings), [1.5, 2.0, 0.0, 0.0, 4.0]);
    }
}
