//! The frame uniform every splat kernel reads (`Frame` in `splat.glsl`,
//! checked against it), the buffers it addresses, and the camera's packing into it.

use bytemuck::{Pod, Zeroable};

use super::*;
use crate::camera::WorldToCameraBlock;
use crate::error::{Error, Result};
use crate::gpu::{Buffer, DeviceAddress, Recording};
use crate::scene::activate::GpuScene;
use crate::scene::{Camera, Projection};

/// Frame parameters shared by every splat kernel: `Frame` in `splat.glsl`
/// (std140; checked against it by `check_layout`). The camera and sizes are
/// set on the host; every address is filled by `FrameUniform::record` in the
/// recording that dispatches with it, which keeps each buffer alive.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct FrameUniform {
    camera: WorldToCameraBlock,
    clip: [f32; 4],
    eye: [f32; 4],
    view_dir: [f32; 4],
    pub(super) background: [f32; 4],
    pub(super) size: [u32; 4],
    pub(super) counts: [u32; 4],
    pub(super) occluder: [f32; 4],
    means: DeviceAddress,
    log_scales: DeviceAddress,
    rotations: DeviceAddress,
    opacity_logits: DeviceAddress,
    sh: DeviceAddress,
    normals: DeviceAddress,
    albedo: DeviceAddress,
    roughness: DeviceAddress,
    metallic: DeviceAddress,
    ao: DeviceAddress,
    visibility: DeviceAddress,
    splats: DeviceAddress,
    features: DeviceAddress,
    tile_counts: DeviceAddress,
    keys: DeviceAddress,
    values: DeviceAddress,
    ranges: DeviceAddress,
    g_rgb: DeviceAddress,
    pair_tiles: DeviceAddress,
    occluder_depth: DeviceAddress,
    g_alpha: DeviceAddress,
    g_depth: DeviceAddress,
    g_median_depth: DeviceAddress,
    g_normal: DeviceAddress,
    g_albedo: DeviceAddress,
    g_roughness: DeviceAddress,
    g_metallic: DeviceAddress,
    g_ao: DeviceAddress,
    g_visibility: DeviceAddress,
    g_top_gaussian: DeviceAddress,
    tile_mask: DeviceAddress,
    visible_slots: DeviceAddress,
    slot_gaussians: DeviceAddress,
    wanted_rows: DeviceAddress,
    pub(super) cull_tiles: [u32; 4],
}
crate::gpu::gpu_layout!(
    FrameUniform,
    "Frame",
    [
        camera.rot0,
        camera.rot1,
        camera.rot2,
        camera.position,
        camera.intrinsics,
        camera.lens0,
        camera.lens1,
        camera.lens2,
        camera.lens3,
        clip,
        eye,
        view_dir,
        background,
        size,
        counts,
        occluder,
        means,
        log_scales,
        rotations,
        opacity_logits,
        sh,
        normals,
        albedo,
        roughness,
        metallic,
        ao,
        visibility,
        splats,
        features,
        tile_counts,
        keys,
        values,
        ranges,
        g_rgb,
        pair_tiles,
        occluder_depth,
        g_alpha,
        g_depth,
        g_median_depth,
        g_normal,
        g_albedo,
        g_roughness,
        g_metallic,
        g_ao,
        g_visibility,
        g_top_gaussian,
        tile_mask,
        visible_slots,
        slot_gaussians,
        wanted_rows,
        cull_tiles
    ]
);

/// The buffers a splat frame's kernels reach by address.
pub(crate) struct FrameBuffers<'b> {
    pub(crate) scene: &'b GpuScene,
    /// Absent before a compacted frame's records are counted.
    pub(crate) splats: Option<&'b Buffer>,
    pub(crate) features: Option<&'b Buffer>,
    pub(crate) tile_counts: Option<&'b Buffer>,
    /// Absent before the sort's buffers exist and after they are freed.
    pub(crate) keys: Option<&'b Buffer>,
    pub(crate) values: Option<&'b Buffer>,
    pub(crate) pair_tiles: Option<&'b Buffer>,
    pub(crate) ranges: &'b Buffer,
    pub(crate) out: &'b GpuGBuffer,
    /// The host's depth per pixel, where splats behind it are hidden.
    pub(crate) occluder: Option<&'b Buffer>,
    /// One u32 per tile, non-zero where pairs are wanted (`TILE_MASK` kernels).
    pub(crate) tile_mask: Option<&'b Buffer>,
    /// Compacted records ([`SplatSettings::compact_splats`]): each Gaussian's
    /// flag, then slot (n + 1 u32), until the records are written.
    pub(crate) visible_slots: Option<&'b Buffer>,
    /// Compacted records: each record's Gaussian.
    pub(crate) slot_gaussians: Option<&'b Buffer>,
    /// With a tile mask: each tile row's wanted columns `[x0, x1)` (uvec2 a row).
    pub(crate) wanted_rows: Option<&'b Buffer>,
}

impl FrameUniform {
    /// Takes every address from `b` through `rec` (which keeps the buffers
    /// borrowed until it is submitted) and writes the uniform into `uniform`
    /// as a recorded command.
    pub(crate) fn record<'a>(
        mut self,
        rec: &mut Recording<'a>,
        uniform: &'a Buffer,
        b: &FrameBuffers<'a>,
    ) -> Result<()> {
        let s = b.scene;
        self.means = rec.addr(&s.means)?;
        self.log_scales = rec.addr(&s.log_scales)?;
        self.rotations = rec.addr(&s.rotations)?;
        self.opacity_logits = rec.addr(&s.opacity_logits)?;
        self.sh = rec.addr(&s.sh)?;
        self.normals = rec.addr_or_null(s.normals.as_ref())?;
        self.albedo = rec.addr_or_null(s.albedo.as_ref())?;
        self.roughness = rec.addr_or_null(s.roughness.as_ref())?;
        self.metallic = rec.addr_or_null(s.metallic.as_ref())?;
        self.ao = rec.addr_or_null(s.ao.as_ref())?;
        self.visibility = rec.addr_or_null(s.visibility.as_ref())?;
        self.splats = rec.addr_or_null(b.splats)?;
        self.features = rec.addr_or_null(b.features)?;
        self.tile_counts = rec.addr_or_null(b.tile_counts)?;
        self.keys = rec.addr_or_null(b.keys)?;
        self.values = rec.addr_or_null(b.values)?;
        self.ranges = rec.addr(b.ranges)?;
        self.pair_tiles = rec.addr_or_null(b.pair_tiles)?;
        self.occluder_depth = rec.addr_or_null(b.occluder)?;
        let o = b.out;
        self.g_rgb = rec.addr_or_null(o.rgb.as_ref())?;
        self.g_alpha = rec.addr(&o.alpha)?;
        self.g_depth = rec.addr_or_null(o.get(Channel::Depth))?;
        self.g_median_depth = rec.addr_or_null(o.get(Channel::MedianDepth))?;
        self.g_normal = rec.addr_or_null(o.get(Channel::Normal))?;
        self.g_albedo = rec.addr_or_null(o.get(Channel::Albedo))?;
        self.g_roughness = rec.addr_or_null(o.get(Channel::Roughness))?;
        self.g_metallic = rec.addr_or_null(o.get(Channel::Metallic))?;
        self.g_ao = rec.addr_or_null(o.get(Channel::Ao))?;
        self.g_visibility = rec.addr_or_null(o.get(Channel::Visibility))?;
        self.g_top_gaussian = rec.addr_or_null(o.top_gaussian.as_ref())?;
        self.tile_mask = rec.addr_or_null(b.tile_mask)?;
        self.visible_slots = rec.addr_or_null(b.visible_slots)?;
        self.slot_gaussians = rec.addr_or_null(b.slot_gaussians)?;
        self.wanted_rows = rec.addr_or_null(b.wanted_rows)?;
        Ok(rec.update(uniform, 0, &self)?)
    }
}

/// Camera parameters for the frame uniform.
pub(super) fn camera_frame(camera: &Camera, frame: &mut FrameUniform) -> Result<()> {
    if camera.width == 0 || camera.height == 0 {
        return Err(Error::invalid(format!("image size {}x{}", camera.width, camera.height), "is empty"));
    }
    let lensed = !camera.lens.is_pinhole();
    if camera.lens.gpu_kind().is_none() || lensed && matches!(camera.projection, Projection::Orthographic { .. }) {
        return Err(Error::invalid(
            format!("camera \"{}\" with lens {:?}", camera.name, camera.lens),
            "is not rendered (splatting renders pinhole cameras with every lens, and orthographic ones without)",
        ));
    }
    let p = camera.packed();
    frame.camera = p.to_camera;
    // The Jacobian's clamp: 1.3 × tan of the half field of view (docs/conventions.md §3).
    let limits = match camera.projection {
        Projection::Pinhole { fx, fy, .. } => {
            [1.3 * 0.5 * camera.width as f32 / fx, 1.3 * 0.5 * camera.height as f32 / fy]
        }
        Projection::Orthographic { .. } => [0.0, 0.0],
    };
    frame.clip = [camera.near, camera.far, limits[0], limits[1]];
    if camera.depth_is_distance() {
        // Equirectangular: no Jacobian clamp; z: the wrap period of a full panorama (0: none).
        frame.clip = [camera.near, camera.far, camera.wrap_period().unwrap_or(0.0), 0.0];
    }
    let eye = p.to_world.position;
    frame.eye = [eye[0], eye[1], eye[2], 0.0];
    let view = camera.rotation.z_axis;
    frame.view_dir = [view.x, view.y, view.z, 0.0];
    let valid = frame.camera.position.iter().chain(&frame.camera.intrinsics).chain(&frame.clip).all(|v| v.is_finite());
    if !valid || camera.near.partial_cmp(&camera.far) != Some(std::cmp::Ordering::Less) {
        return Err(Error::invalid("camera", "has non-finite or inverted parameters"));
    }
    Ok(())
}

/// The split blend's push constants (`ChunkPush` in `splat_blend_body.glsl`;
/// checked by `check_layout`): each tile's first chunk slot (scanned
/// `list_chunks`, then the total), the chunks' transmittance per pixel and
/// their partial sums. Zero where no list is split.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct ChunkPush {
    pub slots: DeviceAddress,
    pub transmittance: DeviceAddress,
    pub partials: DeviceAddress,
}
crate::gpu::gpu_layout!(ChunkPush, "ChunkPush", [slots, transmittance, partials]);

/// `splat_chunk_counts.comp`'s push constants: where each tile's chunk count goes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct ChunkCountPush {
    pub counts: DeviceAddress,
}
crate::gpu::gpu_layout!(ChunkCountPush, "ChunkCountPush", [counts]);

#[cfg(test)]
mod layout_tests {
    use super::backward::BackwardUniform;
    use super::{ChunkCountPush, ChunkPush, FrameUniform};
    use crate::gpu::{check_layout, kernels};

    /// The host structs match the GLSL blocks of every kernel that declares them.
    #[test]
    fn uniform_layouts_match_glsl() {
        let frame = check_layout::<FrameUniform>(kernels::ALL);
        assert!(frame.as_ref().is_ok_and(|n| *n >= 6), "{frame:?}");
        let backward = check_layout::<BackwardUniform>(kernels::ALL);
        assert!(backward.as_ref().is_ok_and(|n| *n == 2), "{backward:?}");
        let chunks = check_layout::<ChunkPush>(kernels::ALL);
        assert!(chunks.as_ref().is_ok_and(|n| *n >= 1), "{chunks:?}");
        let counts = check_layout::<ChunkCountPush>(kernels::ALL);
        assert!(counts.as_ref().is_ok_and(|n| *n == 1), "{counts:?}");
    }
}
