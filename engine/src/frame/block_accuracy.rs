//! A relight setting's whole shadow chain (receiver depth, map depth, bias,
//! filtering) measured against the analytic block's ray-cast truth
//! ([`crate::scene::blocks`]): every sun of the block, every camera, the
//! setting's render size, map fit and visibility kind, as `srug relight`
//! would run them. The tests hold floors on it; `srug bench shadow` prints it.

use super::RelightSettings;
use crate::camera::Camera;
use crate::error::{Error, Result};
use crate::gpu::Device;
use crate::scene::activate::GpuScene;
use crate::scene::blocks::{BlockCity, BlockSun};
use crate::shadow::accuracy::{shadow_accuracy, ShadowAccuracy};
use crate::shadow::{ShadowFit, ShadowPass, Sun};
use crate::splat::{SplatSettings, Splatter};

/// One view's visibility and truth, for callers that check or save them.
pub struct BlockView<'a> {
    /// The sun.
    pub sun: &'a BlockSun,
    /// The camera at the setting's render size.
    pub camera: &'a Camera,
    /// V per pixel.
    pub visibility: &'a [f32],
    /// The truth per pixel (`Some(true)` lit, `None` unknown).
    pub truth: &'a [Option<bool>],
}

/// The accuracy of `settings`' shadows on `city` (uploaded as `scene`), per
/// sun in the block's order; edge errors in pixels of the block's full-size
/// cameras. Outputs are pre-filled with `prefill` when given; `view` sees
/// every view's visibility and truth.
#[allow(clippy::too_many_arguments, reason = "the stages' state, the problem, the setting and the callers' hooks")]
pub fn block_shadow_accuracy(
    device: &Device,
    splatter: &mut Splatter,
    pass: &ShadowPass,
    city: &BlockCity,
    scene: &GpuScene,
    settings: &RelightSettings,
    prefill: Option<u32>,
    view: &mut dyn FnMut(&BlockView<'_>) -> Result<()>,
) -> Result<Vec<(&'static str, ShadowAccuracy)>> {
    let mut st = settings.shadow;
    st.prefill = prefill;
    let bounds = city.scene.bounds().ok_or_else(|| Error::invalid("analytic block", "has no Gaussians"))?;
    let full_width = city.cameras.first().map_or(1, |c| c.width);
    let mut out = Vec::with_capacity(city.suns.len());
    for sun in &city.suns {
        let light = Sun::from_direction(sun.direction, [1.0; 3])?;
        let up = || Error::invalid(format!("block sun \"{}\"", sun.name), "is below the horizon");
        // One map per sun, or per camera where it is fitted to the view.
        let scene_map = match st.fit {
            ShadowFit::SceneBounds => {
                Some(pass.shadow_map(splatter, scene, &bounds, &light, &st, None)?.ok_or_else(up)?)
            }
            ShadowFit::ViewFrustum | ShadowFit::Cascades => None,
        };
        let mut per_sun = ShadowAccuracy::default();
        for camera in &city.cameras {
            let camera = settings.render_camera(camera);
            let splat = SplatSettings { prefill, tile: settings.tile, ..st.receiver_splat() };
            let (g, _) = splatter.render(scene, &camera, &splat)?;
            let kind = settings.visibility_kind;
            let (v, _) = match (&scene_map, st.fit) {
                (Some(map), _) => pass.visibility(map, &g, &camera, &st, kind)?,
                (None, ShadowFit::Cascades) => {
                    let (v, _, t) =
                        pass.cascaded_visibility(splatter, scene, &bounds, &light, &st, &g, &camera, kind, true)?;
                    (v, t)
                }
                (None, _) => {
                    let map = pass.shadow_map(splatter, scene, &bounds, &light, &st, Some(&camera))?.ok_or_else(up)?;
                    pass.visibility(&map, &g, &camera, &st, kind)?
                }
            };
            let v: Vec<f32> = device.read_buffer(&v)?;
            let truth = city.true_visibility(&camera, sun.direction);
            view(&BlockView { sun, camera: &camera, visibility: &v, truth: &truth })?;
            let mut acc = shadow_accuracy(&v, &truth, camera.width as usize, camera.height as usize);
            acc.edge_distance_sum *= f64::from(full_width) / f64::from(camera.width);
            per_sun.add(&acc);
        }
        out.push((sun.name, per_sun));
    }
    Ok(out)
}
