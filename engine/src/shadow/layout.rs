//! The shadow kernels' uniform (`Shadow` in `shadow.glsl`, checked against
//! it), the buffers it reads, and its camera and light packing.

use bytemuck::{Pod, Zeroable};

use crate::camera::CameraToWorldBlock;

use super::*;
use crate::error::{Error, Result};
use crate::gpu::{Buffer, DeviceAddress, Recording};
use crate::scene::Camera;
use crate::splat::Channel;
use crate::splat::GpuGBuffer;

/// The shadow kernels' uniform: `Shadow` in `shadow.glsl` (std140; checked
/// against it by `check_layout`). Addresses are filled by
/// `ShadowUniform::record` in the recording that dispatches with it.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct ShadowUniform {
    pub(super) camera: CameraToWorldBlock,
    pub(super) light_rot0: [f32; 4],
    pub(super) light_rot1: [f32; 4],
    pub(super) light_rot2: [f32; 4],
    pub(super) camera_in_light: [f32; 4],
    pub(super) light_intr: [f32; 4],
    pub(super) size: [u32; 4],
    pub(super) params: [f32; 4],
    pub(super) modes: [u32; 4],
    pub(super) geometry: [f32; 4],
    pub(super) receiver_range: [f32; 4],
    pub(super) receiver_depth: DeviceAddress,
    pub(super) receiver_alpha: DeviceAddress,
    pub(super) map_depth: DeviceAddress,
    pub(super) map_alpha: DeviceAddress,
    pub(super) visibility: DeviceAddress,
    pub(super) receiver_normal: DeviceAddress,
    pub(super) splats: DeviceAddress,
    pub(super) sorted_gaussians: DeviceAddress,
    pub(super) ranges: DeviceAddress,
    pub(super) tile_mask: DeviceAddress,
}
crate::gpu::gpu_layout!(
    ShadowUniform,
    "Shadow",
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
        light_rot0,
        light_rot1,
        light_rot2,
        camera_in_light,
        light_intr,
        size,
        params,
        modes,
        geometry,
        receiver_range,
        receiver_depth,
        receiver_alpha,
        map_depth,
        map_alpha,
        visibility,
        receiver_normal,
        splats,
        sorted_gaussians,
        ranges,
        tile_mask
    ]
);

impl ShadowUniform {
    /// Writes the uniform for `shadow_receiver_tiles.comp`: the receivers'
    /// addresses and the tile mask it marks.
    pub(crate) fn record_receiver_tiles<'a>(
        mut self,
        rec: &mut Recording<'a>,
        uniform: &'a Buffer,
        receivers: &ReceiverInputs<'a>,
        mask: &'a Buffer,
    ) -> Result<()> {
        self.receiver_depth = rec.addr(receivers.receiver_depth)?;
        self.receiver_alpha = rec.addr(receivers.receiver_alpha)?;
        self.receiver_normal = rec.addr_or_null(receivers.receiver_normal)?;
        self.tile_mask = rec.addr(mask)?;
        Ok(rec.update(uniform, 0, &self)?)
    }

    /// Takes every address through `rec` (which keeps the buffers borrowed
    /// until it is submitted) and writes the uniform into `uniform`.
    /// `visibility` is the forward's output (none in the backward pass).
    pub(crate) fn record<'a>(
        mut self,
        rec: &mut Recording<'a>,
        uniform: &'a Buffer,
        inputs: &ShadowInputs<'a>,
        visibility: Option<&'a Buffer>,
    ) -> Result<()> {
        self.receiver_depth = rec.addr(inputs.receiver_depth)?;
        self.receiver_alpha = rec.addr(inputs.receiver_alpha)?;
        self.receiver_normal = rec.addr_or_null(inputs.receiver_normal)?;
        self.map_depth = rec.addr(inputs.map_depth)?;
        self.map_alpha = rec.addr(&inputs.map.frame.gbuffer.alpha)?;
        self.visibility = rec.addr_or_null(visibility)?;
        self.splats = rec.addr(&inputs.map.frame.splats)?;
        self.sorted_gaussians = rec.addr(&inputs.map.frame.sorted_gaussians)?;
        self.ranges = rec.addr(&inputs.map.frame.ranges)?;
        Ok(rec.update(uniform, 0, &self)?)
    }
}

/// `CascadePush` in `shadow_cascade_blend.comp` (its layout is checked against it).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct CascadePush {
    pub(super) visibility01: [DeviceAddress; 2],
    pub(super) visibility23: [DeviceAddress; 2],
    pub(super) blended: DeviceAddress,
    pub(super) count: u32,
    pub(super) pixels: u32,
    pub(super) far: [f32; 4],
    pub(super) blend_start: [f32; 4],
}
crate::gpu::gpu_layout!(
    CascadePush,
    "CascadePush",
    [visibility01, visibility23, blended, count, pixels, far, blend_start]
);

/// `TileDilatePush` in `shadow_tile_dilate.comp` (its layout is checked against it).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct TileDilatePush {
    pub(super) centres: DeviceAddress,
    pub(super) wanted: DeviceAddress,
    pub(super) tiles_x: u32,
    pub(super) tiles_y: u32,
}
crate::gpu::gpu_layout!(TileDilatePush, "TileDilatePush", [centres, wanted, tiles_x, tiles_y]);

/// The buffers the shadow kernels read: the receiver's and the map's depth
/// channels the settings select, the receiver's alpha, and the map itself.
pub(crate) struct ShadowInputs<'a> {
    pub(crate) receiver_depth: &'a Buffer,
    pub(crate) receiver_alpha: &'a Buffer,
    /// The receivers' normals, where the settings ask for a geometric bias.
    pub(crate) receiver_normal: Option<&'a Buffer>,
    pub(crate) map_depth: &'a Buffer,
    pub(crate) map: &'a ShadowMap,
}

/// The receivers' buffers the shadow kernels read.
pub(crate) struct ReceiverInputs<'a> {
    pub(crate) receiver_depth: &'a Buffer,
    pub(crate) receiver_alpha: &'a Buffer,
    /// The receivers' normals, where the settings ask for a geometric bias.
    pub(crate) receiver_normal: Option<&'a Buffer>,
}

/// The shadow kernels' uniform (without addresses) for receivers `gbuffer`
/// seen from `camera` and a map of `depth` from `light` splatted in tiles of
/// `tile` texels, `tiles_x` across; and the receivers' buffers it reads.
pub(super) fn receiver_uniform<'a>(
    light: &Camera,
    depth: DepthMode,
    (tiles_x, tile): (u32, u32),
    gbuffer: &'a GpuGBuffer,
    camera: &Camera,
    settings: &ShadowSettings,
) -> Result<(ShadowUniform, ReceiverInputs<'a>)> {
    settings.validate()?;
    if (gbuffer.width, gbuffer.height) != (camera.width, camera.height) {
        return Err(Error::invalid(
            format!("G-buffer {}x{}", gbuffer.width, gbuffer.height),
            format!("does not match camera {}x{}", camera.width, camera.height),
        ));
    }
    let receiver_depth = match settings.receiver_depth {
        DepthMode::Median => gbuffer.get(Channel::MedianDepth),
        DepthMode::Expected | DepthMode::ExpectedOverFar => gbuffer.get(Channel::Depth),
    }
    .ok_or_else(|| {
        Error::invalid(
            "receiver G-buffer",
            format!("lacks the {:?} depth channel the shadow settings ask for", settings.receiver_depth),
        )
    })?;
    let receiver_normal = if settings.geometric_bias() {
        Some(gbuffer.get(Channel::Normal).ok_or_else(|| {
            Error::invalid("receiver G-buffer", "lacks the normal channel a slope bias or normal offset needs")
        })?)
    } else {
        None
    };
    let mut u = ShadowUniform::zeroed();
    u.camera = camera.packed().to_world;
    let packed = light.packed().to_camera;
    [u.light_rot0, u.light_rot1, u.light_rot2] = [packed.rot0, packed.rot1, packed.rot2];
    // The receivers' camera in light space, in f64 and rounded once (`light_coords` in shadow.glsl).
    let c = light.rotation.as_dmat3().transpose() * (camera.position.as_dvec3() - light.position.as_dvec3());
    u.camera_in_light = [c.x as f32, c.y as f32, c.z as f32, light.far];
    u.light_intr = packed.intrinsics;
    u.size = [camera.width, camera.height, light.width, light.height];
    u.params = [settings.k, settings.bias, settings.min_alpha, depth.empty_depth(light.far)];
    u.modes = [depth.code(), settings.receiver_depth.code(), tiles_x, tile];
    let texel = texel_size(light);
    u.geometry = [settings.slope_bias * texel, settings.normal_offset * texel, MAX_SLOPE, 0.0];
    u.receiver_range = [0.0, f32::MAX, 0.0, 0.0];
    Ok((u, ReceiverInputs { receiver_depth, receiver_alpha: &gbuffer.alpha, receiver_normal }))
}

/// The shadow kernels' uniform (without addresses) for `map`, receivers
/// `gbuffer` seen from `camera`, and `settings`, and the buffers it reads.
pub(super) fn shadow_uniform<'a>(
    map: &'a ShadowMap,
    gbuffer: &'a GpuGBuffer,
    camera: &Camera,
    settings: &ShadowSettings,
) -> Result<(ShadowUniform, ShadowInputs<'a>)> {
    if settings.map_depth != map.depth {
        return Err(Error::invalid(
            format!("shadow map of {:?} depth", map.depth),
            format!("does not match the settings' {:?} depth", settings.map_depth),
        ));
    }
    let tiles = (map.frame.tiles().0, map.frame.tile);
    let (u, r) = receiver_uniform(&map.camera, map.depth, tiles, gbuffer, camera, settings)?;
    let g = &map.frame.gbuffer;
    let map_depth = match map.depth {
        DepthMode::Median => g.get(Channel::MedianDepth),
        DepthMode::Expected | DepthMode::ExpectedOverFar => g.get(Channel::Depth),
    }
    .ok_or_else(|| Error::Internal("the shadow map lacks its depth channel".into()))?;
    let inputs = ShadowInputs {
        receiver_depth: r.receiver_depth,
        receiver_alpha: r.receiver_alpha,
        receiver_normal: r.receiver_normal,
        map_depth,
        map,
    };
    Ok((u, inputs))
}

#[cfg(test)]
mod layout_tests {
    use super::backward::{BinsPush, ShadowBackwardUniform};
    use super::ShadowUniform;
    use crate::gpu::{check_layout, kernels};

    /// The host structs match the GLSL blocks of every kernel that declares them.
    #[test]
    fn uniform_layouts_match_glsl() {
        let shadow = check_layout::<ShadowUniform>(kernels::ALL);
        assert!(shadow.as_ref().is_ok_and(|n| *n >= 4), "{shadow:?}");
        let backward = check_layout::<ShadowBackwardUniform>(kernels::ALL);
        assert!(backward.as_ref().is_ok_and(|n| *n >= 2), "{backward:?}");
        assert_eq!(check_layout::<BinsPush>(&[&kernels::SHADOW_BINS]), Ok(1));
        assert_eq!(check_layout::<super::CascadePush>(&[&kernels::SHADOW_CASCADE_BLEND]), Ok(1));
        assert_eq!(check_layout::<super::TileDilatePush>(&[&kernels::SHADOW_TILE_DILATE]), Ok(1));
    }
}
