//! The block the scene's activation kernel reads (`ActivatePush` in
//! `scene_activate.comp`, checked against it).

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

#[cfg(test)]
mod layout_tests {
    use super::ActivatePush;
    use crate::gpu::{check_layout, kernels};

    /// The push-constant struct matches the GLSL block of its kernel.
    #[test]
    fn push_layout_matches_glsl() {
        assert_eq!(check_layout::<ActivatePush>(&[&kernels::SCENE_ACTIVATE]), Ok(1));
    }
}
