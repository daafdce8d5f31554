//! The blocks the scene's kernels read (`ActivatePush` in
//! `scene_activate.comp`, `ReorderPush` in `scene_reorder.comp`; each checked
//! against its GLSL).

use bytemuck::{Pod, Zeroable};

use crate::gpu::DeviceAddress;

/// Push constants of `scene_activate.comp` (its `ActivatePush` block; checked by `check_layout`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct ActivatePush {
    /// `float[3N]` log scales.
    pub log_scales: DeviceAddress,
    /// `float[4N]` quaternions.
    pub rotations: DeviceAddress,
    /// `float[N]` opacity logits.
    pub opacity_logits: DeviceAddress,
    /// The `float[6N]` covariance output.
    pub covariances: DeviceAddress,
    /// The `float[N]` opacity output.
    pub opacities: DeviceAddress,
    /// N.
    pub count: u32,
    /// Padding to the GLSL block size.
    pub pad: u32,
}
crate::gpu::gpu_layout!(
    ActivatePush,
    "ActivatePush",
    [log_scales, rotations, opacity_logits, covariances, opacities, count, pad]
);

/// Push constants of `scene_reorder.comp` (its `ReorderPush` block; checked by `check_layout`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct ReorderPush {
    /// The words read.
    pub src: DeviceAddress,
    /// The words written.
    pub dst: DeviceAddress,
    /// `uint[count]` rows to read (null: row i), or the ids' map.
    pub index: DeviceAddress,
    /// Rows (or ids) to write.
    pub count: u32,
    /// Words a row moves; for ids, the map's length.
    pub width: u32,
    /// Words from one source row to the next.
    pub src_stride: u32,
    /// First word moved within a source row.
    pub src_first: u32,
    /// Words from one destination row to the next.
    pub dst_stride: u32,
    /// First word written within a destination row.
    pub dst_first: u32,
}
crate::gpu::gpu_layout!(
    ReorderPush,
    "ReorderPush",
    [src, dst, index, count, width, src_stride, src_first, dst_stride, dst_first]
);

#[cfg(test)]
mod layout_tests {
    use super::{ActivatePush, ReorderPush};
    use crate::gpu::{check_layout, kernels};

    /// The push-constant struct matches the GLSL block of its kernel.
    #[test]
    fn push_layout_matches_glsl() {
        assert_eq!(check_layout::<ActivatePush>(&[&kernels::SCENE_ACTIVATE]), Ok(1));
        assert_eq!(check_layout::<ReorderPush>(&[&kernels::SCENE_REORDER]), Ok(1));
    }
}
