//! What a frame of a scene will run, before anything runs (`srug info --plan`):
//! its stages, the G-buffer channels and shader variants they use, and the GPU
//! memory known ahead. It is built from [`RelightDecisions`], the same
//! decisions [`crate::frame::Relighter::render`] follows, so the plan
//! and the renderer cannot disagree: no materials → plain colour and no
//! shading; no sun above the horizon → no shadow pass; no network → no inference.

use std::fmt::Write as _;

use crate::error::Result;
use crate::frame::{RelightDecisions, RelightSettings};
use crate::indirect::{StoragePrecision, UNetConfig};
use crate::scene::{human_bytes, Scene};
use crate::shadow::{depth_channels, light_camera, Sun};
use crate::splat::{BlendVariant, Channel, Channels, PACKED_FEATURE_BYTES, SPLAT_BYTES};

/// What the plan is for.
#[derive(Clone, Debug)]
pub struct PlanSettings<'a> {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// The sun (`None`, or below the horizon: no sun light).
    pub sun: Option<Sun>,
    /// Relighting settings.
    pub relight: RelightSettings,
    /// The indirect-light network, when weights are given.
    pub network: Option<(&'a UNetConfig, StoragePrecision)>,
    /// The blend kernel the device will use.
    pub blend: BlendVariant,
}

/// One stage that will run.
#[derive(Clone, Debug, PartialEq)]
pub struct PlannedStage {
    /// What it is.
    pub name: String,
    /// Its kernels and their variants.
    pub kernels: String,
    /// GPU bytes it allocates that are known before rendering.
    pub bytes: u64,
    /// What else it allocates, in words, when that depends on the view.
    pub note: String,
}

/// A frame's plan.
#[derive(Clone, Debug)]
pub struct FramePlan {
    /// The decisions the renderer follows.
    pub decisions: RelightDecisions,
    /// Stages that run, in order.
    pub stages: Vec<PlannedStage>,
    /// Stages that do not run, each with the reason.
    pub skipped: Vec<String>,
    /// GPU bytes of the scene's parameters.
    pub scene_bytes: u64,
}

impl FramePlan {
    /// Scene plus every stage's known bytes.
    pub(crate) fn known_bytes(&self) -> u64 {
        self.scene_bytes + self.stages.iter().map(|s| s.bytes).sum::<u64>()
    }

    /// The plan as text for `srug info --plan`.
    pub fn text(&self) -> String {
        let mut t = String::new();
        let _ = writeln!(t, "stages:");
        for s in &self.stages {
            let _ = writeln!(t, "  {:<22} {} ({}{})", s.name, s.kernels, human_bytes(s.bytes), s.note);
        }
        if !self.skipped.is_empty() {
            let _ = writeln!(t, "not run:");
            for s in &self.skipped {
                let _ = writeln!(t, "  {s}");
            }
        }
        let _ = writeln!(
            t,
            "GPU memory known ahead: {} (scene {})",
            human_bytes(self.known_bytes()),
            human_bytes(self.scene_bytes)
        );
        t
    }
}

/// Channel names, rgb (when blended) and alpha first.
pub(crate) fn channel_names(c: Channels, rgb: bool) -> Vec<&'static str> {
    let mut v: Vec<&'static str> = if rgb { vec!["rgb", "alpha"] } else { vec!["alpha"] };
    v.extend(c.iter().map(Channel::name));
    v
}

/// Floats per pixel of a G-buffer with these channels (alpha and, when blended, rgb included).
fn floats_per_pixel(c: Channels, rgb: bool) -> u64 {
    1 + 3 * u64::from(rgb) + c.iter().map(|ch| ch.floats() as u64).sum::<u64>()
}

fn splat_stage(
    name: &str,
    n: u64,
    texels: u64,
    (channels, rgb): (Channels, bool),
    blend: BlendVariant,
    (tile, surface_depth): (u32, bool),
) -> PlannedStage {
    // The relighter stores its splats' features at 16 bits (`SplatSettings::packed_features`),
    // for the Gaussians in view only (`SplatSettings::compact_splats`): at most every Gaussian's.
    let features = if channels.needs_features() { n * PACKED_FEATURE_BYTES } else { 0 };
    PlannedStage {
        name: name.to_string(),
        kernels: format!(
            "preprocess, scan, keys, radix sort, ranges, blend {blend:?}{} with CHANNELS = {:#011b} [{}], \
             {tile}×{tile} tiles, {} depths",
            if blend == BlendVariant::SubgroupLoads {
                " (texel-buffer reads where the device has the views and the pairs fit them)"
            } else {
                ""
            },
            channels.blend_bits(rgb),
            channel_names(channels, rgb).join(", "),
            if surface_depth { "surface" } else { "centre" }
        ),
        bytes: texels * floats_per_pixel(channels, rgb) * 4 + n * SPLAT_BYTES + features,
        note: "; keys and sort scratch grow with the (Gaussian, tile) pairs".into(),
    }
}

/// Plans a frame of `scene`.
pub fn plan_frame(scene: &Scene, settings: &PlanSettings<'_>) -> Result<FramePlan> {
    let attributes = scene.attributes();
    let d = RelightDecisions::new(&attributes, settings.sun.as_ref(), &settings.relight)?;
    let n = scene.len() as u64;
    settings.relight.validate()?;
    // The frame is splatted and shaded at the render scale.
    let (width, height) = settings.relight.render_size(settings.width, settings.height);
    let pixels = u64::from(width) * u64::from(height);
    let camera = (d.channels, true);
    // The camera's depths are the shadow's receivers' (Relighter's splat settings).
    let camera_splat = (settings.relight.tile, settings.relight.shadow.surface_depth);
    let mut stages = vec![splat_stage("splat (camera)", n, pixels, camera, settings.blend, camera_splat)];
    let mut skipped = Vec::new();
    if !d.shading {
        skipped.push("shading: the scene has no albedo attribute (its plain 3DGS colour is the image)".into());
    }
    match (d.shadow_pass, d.sun) {
        (true, Some(sun)) => {
            let st = &settings.relight.shadow;
            // Cascades: that many square maps, each fitted to its camera's slice.
            let texels = match st.fit {
                crate::shadow::ShadowFit::Cascades => u64::from(st.cascades) * u64::from(st.resolution).pow(2),
                _ => scene
                    .bounds()
                    .and_then(|b| light_camera(&b, &sun, st.resolution, st.fit, None).ok())
                    .map_or(u64::from(st.resolution).pow(2), |c| u64::from(c.width) * u64::from(c.height)),
            };
            // Shadow maps blend no colour (ShadowPass::shadow_map_from).
            let map_channels = (depth_channels(st.map_depth), false);
            let map_splat = (st.tile, st.map_surface_depth);
            let mut map = splat_stage("splat (shadow map)", n, texels, map_channels, settings.blend, map_splat);
            if st.map_depth == crate::shadow::DepthMode::Median {
                map.note.push_str(&format!("; occluder depths where coverage reaches {}", st.map_coverage));
            }
            map.note.push_str(
                "; with shadow-map reuse on (`srug relight`), later frames skip it while the scene, the sun's \
                 direction and the light camera stay the same",
            );
            stages.push(map);
            let traced = settings.relight.visibility_kind == crate::shadow::VisibilityKind::Traced;
            stages.push(PlannedStage {
                name: if traced { "traced shadow test" } else { "sigmoid shadow test" }.into(),
                kernels: if traced {
                    format!("shadow_traced, bias = {}", st.bias)
                } else {
                    format!(
                        "shadow_test, filter {}, k = {}, bias = {} m + {} texels × tan θ",
                        st.filter.name(),
                        st.k,
                        st.bias,
                        st.slope_bias
                    )
                },
                bytes: pixels * 4,
                note: String::new(),
            });
        }
        _ if d.shading => skipped.push(match (d.sun, settings.relight.shade.visibility) {
            (None, _) => "shadow pass: no sun above the horizon (no sun light either)".into(),
            (Some(_), v) => format!("shadow pass: visibility is {v:?}"),
        }),
        _ => {}
    }
    if d.shading {
        stages.push(PlannedStage {
            name: "shading".into(),
            kernels: format!(
                "shade_lights, shade_compose (sun {}, visibility {:?}, tone map {:?})",
                if d.sun.is_some() { "on" } else { "off" },
                d.visibility,
                settings.relight.shade.tone_map
            ),
            // L_sun, L_sky, radiance and display, 3 floats each.
            bytes: pixels * 48,
            note: "; plus the prepared environment and the BRDF table, made once".into(),
        });
        match settings.network {
            Some((config, precision)) => stages.push(PlannedStage {
                name: "indirect light (U-Net)".into(),
                kernels: {
                    let half = if precision == StoragePrecision::Fp16 { "_half" } else { "" };
                    format!(
                        "unet_pack; on CPU devices (lavapipe) unet_winograd_texel{half} ×6 (the stride-1 layers, \
                         Winograd F(4×4, 3×3); unet_winograd2_texel{half} for F(2×2, 3×3) on request) and \
                         unet_conv_texel{half} ×4 (stride 2), four pixels per fetch where a level's width is a \
                         multiple of 4; on GPUs unet_conv_texel{half} ×10, one pixel per fetch \
                         (unet_conv{half} ×10 by device address where texel views are missing), \
                         unet_upsample_texel{half} ×4 (exactly 2×, from four-pixel texels, where the sizes \
                         and align_corners allow; widths {:?})",
                        config.widths
                    )
                },
                bytes: config.arena_bytes(width, height, precision)
                    + pixels * (config.in_channels as u64 + 3) * 4
                    + config.parameter_count() * 4,
                note: format!("; {precision:?} activation arena, input, output, weights"),
            }),
            None => skipped.push("indirect light: no network weights".into()),
        }
    } else if settings.network.is_some() {
        skipped.push("indirect light: nothing is shaded".into());
    }
    Ok(FramePlan { decisions: d, stages, skipped, scene_bytes: scene.gpu_bytes() })
}
