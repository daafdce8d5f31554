//! Cascaded shadow maps: the receiving camera's view depth cut into slices,
//! a map fitted to each, so texels near the camera are fine and far ones
//! coarse ([`super::ShadowFit::Cascades`]).
//!
//! Invariants:
//! - slices follow the practical split scheme (half logarithmic, half
//!   uniform) between the nearest and the farthest the scene bounds' sphere
//!   can be from the camera, in steps of its radius (0 to the diagonal from
//!   inside the bounds), within the camera's planes, so they change only when
//!   a distant camera crosses a step, and each slice's last tenth is shared with the
//!   next: there the visibility ramps linearly from one cascade to the next
//!   ([`blend_cascades_cpu`], `shadow_cascade_blend.comp`);
//! - a cascade's map is square, `resolution` texels across its slice's
//!   bounding sphere, whose radius depends only on the camera's intrinsics,
//!   and its centre snaps to whole texels of a light-space grid fixed in the
//!   world: a moving or turning camera moves the map by whole texels, so
//!   shadow edges do not shimmer;
//! - every map covers the scene's whole depth along the light, so casters
//!   outside the view still cast into it;
//! - not differentiated ([`super::ShadowPass::backward`] takes one map).

use bytemuck::Zeroable;
use glam::{Vec2, Vec3};

use super::{CascadePush, LightFrame, ShadowMap, ShadowPass, ShadowSettings, Sun, VisibilityKind};
use crate::error::{Error, Result};
use crate::gpu::{Binding, Buffer, DeviceAddress, Grid, MemoryKind, Timings};
use crate::scene::activate::GpuScene;
use crate::scene::{Bounds, Camera, Projection};
use crate::splat::{GpuGBuffer, Splatter};

/// The most cascades ([`ShadowSettings::cascades`]).
pub const MAX_CASCADES: u32 = 4;

/// The share of a slice over which it hands over to the next.
const BLEND: f32 = 0.1;

/// How much of the split is logarithmic (the rest uniform).
const LOG_WEIGHT: f32 = 0.5;

/// One cascade: its light camera and the camera depths it serves.
#[derive(Clone, Debug, PartialEq)]
pub struct Cascade {
    /// The orthographic light camera.
    pub camera: Camera,
    /// The slice's near end (camera z).
    pub near: f32,
    /// The slice's far end (camera z).
    pub far: f32,
    /// From here to `far` the visibility ramps to the next cascade's.
    pub blend_start: f32,
}

impl Cascade {
    /// The world width of one texel of its map.
    pub fn texel(&self) -> f32 {
        super::texel_size(&self.camera)
    }
}

/// The far ends of `count` slices of `near..far` (practical split scheme).
pub fn cascade_splits(near: f32, far: f32, count: u32) -> Vec<f32> {
    (1..=count)
        .map(|i| {
            let f = i as f32 / count as f32;
            let log = near * (far / near).powf(f);
            let uniform = near + (far - near) * f;
            LOG_WEIGHT * log + (1.0 - LOG_WEIGHT) * uniform
        })
        .collect()
}

/// The cascades of `view` (a pinhole camera) for `sun` over a scene of
/// `bounds`: `count` maps of `resolution` texels.
pub fn cascade_cameras(bounds: &Bounds, sun: &Sun, resolution: u32, view: &Camera, count: u32) -> Result<Vec<Cascade>> {
    if !(2..=MAX_CASCADES).contains(&count) {
        return Err(Error::invalid(format!("{count} shadow cascades"), "must be 2 to 4"));
    }
    if !(16..=16384).contains(&resolution) {
        return Err(Error::invalid(format!("shadow map resolution {resolution}"), "must be 16..=16384 texels"));
    }
    if !matches!(view.projection, Projection::Pinhole { .. }) {
        return Err(Error::invalid(
            format!("camera \"{}\"", view.name),
            "is orthographic: cascaded shadow maps slice a pinhole view",
        ));
    }
    view.require_no_lens("cascaded shadow maps")?;
    let frame = LightFrame::new(bounds, sun)?;
    // The view's depth: from the nearest to the farthest the bounds' sphere can be,
    // in steps of its radius r, within the camera's planes. Not the corners in view:
    // the slices, and so the maps' sizes, change only when the camera crosses a step
    // (never for a camera inside the bounds: 0..2r), not as it moves or turns.
    let r = 0.5 * (frame.hi - frame.lo).length();
    let distance = (view.position - frame.centre).length();
    let far = (((distance + r) / r).ceil() * r).min(view.far);
    let near = view.near.max(((distance - r) / r).floor().max(0.0) * r).max(1e-4 * far);
    if far.partial_cmp(&near) != Some(std::cmp::Ordering::Greater) {
        return Err(Error::invalid(format!("camera \"{}\"", view.name), "has its far plane at its near plane"));
    }
    let splits = cascade_splits(near, far, count);
    let mut out = Vec::with_capacity(splits.len());
    let mut slice_near = near;
    for (i, &slice_far) in splits.iter().enumerate() {
        // The slice's bounding sphere in camera space: fixed by the intrinsics.
        let points = slice_points(view, slice_near, slice_far)?;
        let centre = points.iter().fold(Vec3::ZERO, |a, p| a + *p) / points.len() as f32;
        let radius = points.iter().map(|p| (*p - centre).length()).fold(0.0, f32::max);
        let texel = 2.0 * radius / resolution as f32;
        let world = view.rotation * centre + view.position;
        let light = frame.to_light(world).truncate();
        let snapped = (light / texel).round() * texel;
        let half = Vec2::splat(0.5 * resolution as f32 * texel);
        let mut camera = frame.camera(snapped - half, snapped + half, resolution)?;
        camera.name = format!("sun cascade {i}");
        let blend_start = if i + 1 < splits.len() { slice_far - BLEND * (slice_far - slice_near) } else { slice_far };
        out.push(Cascade { camera, near: slice_near, far: slice_far, blend_start });
        slice_near = blend_start;
    }
    Ok(out)
}

/// Camera-space points bounding the slice `near..far` of a pinhole view: its
/// image corners and edge midpoints at both depths.
fn slice_points(view: &Camera, near: f32, far: f32) -> Result<Vec<Vec3>> {
    let (w, h) = (f64::from(view.width), f64::from(view.height));
    let mut points = Vec::with_capacity(16);
    for z in [near, far] {
        for (u, v) in
            [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h), (0.5 * w, 0.0), (0.5 * w, h), (0.0, 0.5 * h), (w, 0.5 * h)]
        {
            let [x, y, d] = view
                .pixel_direction([u, v])
                .ok_or_else(|| Error::invalid(format!("camera \"{}\"", view.name), "has no ray at an image corner"))?;
            points.push(Vec3::new((x / d) as f32 * z, (y / d) as f32 * z, z));
        }
    }
    Ok(points)
}

/// The CPU twin of `shadow_cascade_blend.comp`: each pixel's visibility from
/// the cascades' (`visibilities[c][p]`) by its camera depth (`None`: no
/// surface, the first cascade's V).
pub fn blend_cascades_cpu(visibilities: &[Vec<f64>], depths: &[Option<f64>], cascades: &[Cascade]) -> Vec<f64> {
    let last = cascades.len().saturating_sub(1);
    (0..depths.len())
        .map(|p| {
            let Some(z) = depths[p] else { return visibilities[0][p] };
            let mut c = 0;
            while c < last && z > f64::from(cascades[c].far) {
                c += 1;
            }
            let v = visibilities[c][p];
            let (start, end) = (f64::from(cascades[c].blend_start), f64::from(cascades[c].far));
            if c < last && z > start {
                let t = (z - start) / (end - start);
                v + (visibilities[c + 1][p] - v) * t
            } else {
                v
            }
        })
        .collect()
}

impl ShadowPass {
    /// The receivers' visibility in `gbuffer` (rendered from `camera` with
    /// [`ShadowSettings::receiver_channels`]) from cascaded shadow maps:
    /// each cascade splatted (only where the receivers look it up when
    /// `cull`), tested like [`ShadowPass::visibility`], and the results blended
    /// by depth. Returns the visibility, the cascades and the GPU time.
    #[allow(clippy::too_many_arguments, reason = "the pass's inputs, each of a different stage")]
    pub fn cascaded_visibility(
        &self,
        splatter: &mut Splatter,
        scene: &GpuScene,
        bounds: &Bounds,
        sun: &Sun,
        settings: &ShadowSettings,
        gbuffer: &GpuGBuffer,
        camera: &Camera,
        kind: VisibilityKind,
        cull: bool,
    ) -> Result<(Buffer, Vec<Cascade>, Timings)> {
        settings.validate()?;
        let cascades = cascade_cameras(bounds, sun, settings.resolution, camera, settings.cascades)?;
        let mut timings = Timings::default();
        let mut visibilities = Vec::with_capacity(cascades.len());
        // The last cascade's map, kept for the receivers' uniform of the blend.
        let mut last_map: Option<ShadowMap> = None;
        for (i, cascade) in cascades.iter().enumerate() {
            // Free the previous map before splatting the next.
            drop(last_map.take());
            let map: ShadowMap = if cull {
                // Each cascade is splatted only where the receivers of its own slice look.
                let receivers = [(gbuffer, camera)];
                let first = i == 0;
                let last = i + 1 == cascades.len();
                let depths = (if first { 0.0 } else { cascade.near }, if last { f32::MAX } else { cascade.far });
                let light = cascade.camera.clone();
                self.shadow_map_for_receivers_in(splatter, scene, light, sun, settings, &receivers, depths)?
            } else {
                self.shadow_map_from(splatter, scene, cascade.camera.clone(), sun, settings)?
            };
            let (v, t) = self.visibility(&map, gbuffer, camera, settings, kind)?;
            for stage in map.frame.stats.timings.stages.iter().chain(&t.stages) {
                let mut stage = stage.clone();
                stage.name = format!("{} (cascade {i})", stage.name);
                timings.stages.push(stage);
            }
            visibilities.push(v);
            last_map = Some(map);
        }
        let map = last_map.ok_or_else(|| Error::Internal("cascaded shadow maps without a cascade".into()))?;
        let (blended, t) = self.blend_cascades(&map, gbuffer, camera, settings, &visibilities, &cascades)?;
        timings.stages.extend(t.stages);
        Ok((blended, cascades, timings))
    }

    /// Blends the cascades' visibilities by the receivers' depth (`map`: any
    /// cascade's, for the receivers' uniform).
    fn blend_cascades(
        &self,
        map: &ShadowMap,
        gbuffer: &GpuGBuffer,
        camera: &Camera,
        settings: &ShadowSettings,
        visibilities: &[Buffer],
        cascades: &[Cascade],
    ) -> Result<(Buffer, Timings)> {
        let device = &self.device;
        let pixels = u64::from(camera.width) * u64::from(camera.height);
        let out = device.create_buffer("cascaded visibility", pixels * 4, MemoryKind::Storage)?;
        let (u, inputs) = super::shadow_uniform(map, gbuffer, camera, settings)?;
        let uniform = device.create_buffer(
            "shadow uniform",
            std::mem::size_of::<super::ShadowUniform>() as u64,
            MemoryKind::Storage,
        )?;
        let timings = device.run(|rec| -> Result<()> {
            u.record(rec, &uniform, &inputs, None)?;
            if let Some(word) = settings.prefill {
                rec.fill(&out, word)?;
            }
            let mut push = CascadePush::zeroed();
            let mut addresses = [DeviceAddress::default(); 4];
            for (a, v) in addresses.iter_mut().zip(visibilities) {
                *a = rec.addr(v)?;
            }
            push.visibility01 = [addresses[0], addresses[1]];
            push.visibility23 = [addresses[2], addresses[3]];
            push.blended = rec.addr(&out)?;
            push.count = cascades.len() as u32;
            push.pixels = pixels as u32;
            for (i, c) in cascades.iter().enumerate() {
                push.far[i] = c.far;
                push.blend_start[i] = c.blend_start;
            }
            rec.begin_stage("shadow cascade blend");
            rec.dispatch(&self.cascade_blend, Grid::Items(pixels), &[Binding::from(&uniform)], &push)?;
            rec.end_stage();
            Ok(())
        })?;
        Ok((out, timings))
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::expect_used, reason = "a failed expect is a failed test")]
    use super::*;

    fn bounds() -> Bounds {
        Bounds { min: [-60.0, -40.0, 0.0], max: [60.0, 40.0, 30.0] }
    }

    fn street(eye: Vec3, yaw_degrees: f32) -> Camera {
        let (s, c) = yaw_degrees.to_radians().sin_cos();
        Camera::look_at(eye, eye + Vec3::new(c, s, -0.05), Vec3::Z, 90.0, 704, 192).expect("a camera")
    }

    #[test]
    fn a_distant_camera_gets_slices_over_the_scene() {
        let sun = Sun::from_azimuth_elevation(200.0, 35.0, [1.0; 3]).expect("a sun");
        // 1 km away, looking at the block: the slices start and end around it.
        let far_away =
            Camera::look_at(Vec3::new(-1000.0, 0.0, 200.0), Vec3::ZERO, Vec3::Z, 20.0, 704, 192).expect("a camera");
        let c = cascade_cameras(&bounds(), &sun, 1024, &far_away, 3).expect("cascades");
        let d = far_away.position.length();
        assert!(c[0].near > 0.5 * d && c[0].near < d, "first slice from {}", c[0].near);
        assert!(c[2].far > d && c[2].far < 1.5 * d, "last slice to {}", c[2].far);
        // Inside the bounds: from the camera's near plane to the diagonal.
        let inside =
            cascade_cameras(&bounds(), &sun, 1024, &street(Vec3::new(-20.0, 0.0, 1.6), 10.0), 3).expect("cascades");
        let diagonal = LightFrame::new(&bounds(), &sun).map(|f| (f.hi - f.lo).length()).expect("a frame");
        assert!((inside[2].far - diagonal).abs() < 1e-3 * diagonal);
    }

    #[test]
    fn splits_grow_from_near_to_far() {
        let s = cascade_splits(0.1, 200.0, 4);
        assert_eq!(s.len(), 4);
        assert!((s[3] - 200.0).abs() < 1e-3);
        assert!(s.windows(2).all(|w| w[0] < w[1]) && s[0] > 0.1);
    }

    #[test]
    fn cascade_texels_stay_on_a_grid_fixed_in_the_world() {
        let sun = Sun::from_azimuth_elevation(200.0, 35.0, [1.0; 3]).expect("a sun");
        let frame = LightFrame::new(&bounds(), &sun).expect("a frame");
        let base =
            cascade_cameras(&bounds(), &sun, 1024, &street(Vec3::new(-20.0, 0.0, 1.6), 10.0), 3).expect("cascades");
        // Moved by a fraction of a texel, and turned: the same texel sizes, and each map's
        // origin moves by whole texels.
        for (eye, yaw) in [(Vec3::new(-19.987, 0.013, 1.6), 10.0), (Vec3::new(-18.3, 2.1, 1.6), 37.0)] {
            let moved = cascade_cameras(&bounds(), &sun, 1024, &street(eye, yaw), 3).expect("cascades");
            for (a, b) in base.iter().zip(&moved) {
                let texel = a.texel();
                assert!((texel - b.texel()).abs() <= 1e-6 * texel, "texel {texel} -> {}", b.texel());
                let shift = (frame.to_light(b.camera.position) - frame.to_light(a.camera.position)).truncate() / texel;
                let off_grid = (shift - shift.round()).abs().max_element();
                assert!(off_grid < 1e-2, "a cascade moved by {shift} texels");
            }
        }
    }
}
