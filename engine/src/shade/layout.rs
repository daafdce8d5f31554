//! The shading kernels' uniform (`Shade` in `shade.glsl`, checked against it)
//! and the buffers it addresses.

use bytemuck::{Pod, Zeroable};

use crate::camera::CameraToWorldBlock;

use super::*;
use crate::error::Result;
use crate::gpu::{Buffer, DeviceAddress, Recording};
use crate::splat::Channel;

/// The shading kernels' uniform: `Shade` in `shade.glsl` (std140; checked
/// against it by `check_layout`). Addresses are filled by
/// `ShadeUniform::record` in the recording that dispatches with it.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct ShadeUniform {
    pub(super) camera: CameraToWorldBlock,
    pub(super) size: [u32; 4],
    pub(super) env_size: [u32; 4],
    pub(super) sun_dir: [f32; 4],
    pub(super) sun_radiance: [f32; 4],
    pub(super) env: [f32; 4],
    pub(super) background: [f32; 4],
    pub(super) display: [f32; 4],
    pub(super) modes: [u32; 4],
    pub(super) normal: DeviceAddress,
    pub(super) albedo: DeviceAddress,
    pub(super) roughness: DeviceAddress,
    pub(super) metallic: DeviceAddress,
    pub(super) ao: DeviceAddress,
    pub(super) fixed_visibility: DeviceAddress,
    pub(super) editable_visibility: DeviceAddress,
    pub(super) alpha: DeviceAddress,
    pub(super) specular: DeviceAddress,
    pub(super) irradiance: DeviceAddress,
    pub(super) brdf: DeviceAddress,
    pub(super) l_sun: DeviceAddress,
    pub(super) l_sky: DeviceAddress,
    pub(super) l_ind: DeviceAddress,
    pub(super) out_radiance: DeviceAddress,
    pub(super) out_display: DeviceAddress,
}
crate::gpu::gpu_layout!(
    ShadeUniform,
    "Shade",
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
        size,
        env_size,
        sun_dir,
        sun_radiance,
        env,
        background,
        display,
        modes,
        normal,
        albedo,
        roughness,
        metallic,
        ao,
        fixed_visibility,
        editable_visibility,
        alpha,
        specular,
        irradiance,
        brdf,
        l_sun,
        l_sky,
        l_ind,
        out_radiance,
        out_display
    ]
);

/// The buffers the shading kernels reach by address.
pub(super) struct ShadeBuffers<'b> {
    pub(super) inputs: &'b ShadeInputs<'b>,
    /// The shadow test's V_e when the visibility is editable.
    pub(super) editable: Option<&'b Buffer>,
    /// L_ind: given, or the network's output.
    pub(super) indirect: Option<&'b Buffer>,
    pub(super) sun: &'b Buffer,
    pub(super) sky: &'b Buffer,
    pub(super) radiance: &'b Buffer,
    pub(super) display: &'b Buffer,
}

impl ShadeUniform {
    /// Takes every address from `b` through `rec` (which keeps the buffers
    /// borrowed until it is submitted) and writes the uniform into `uniform`.
    pub(super) fn record<'a>(
        mut self,
        rec: &mut Recording<'a>,
        uniform: &'a Buffer,
        b: &ShadeBuffers<'a>,
    ) -> Result<()> {
        let g = b.inputs.gbuffer;
        let env = b.inputs.environment;
        self.normal = rec.addr_or_null(g.get(Channel::Normal))?;
        self.albedo = rec.addr_or_null(g.get(Channel::Albedo))?;
        self.roughness = rec.addr_or_null(g.get(Channel::Roughness))?;
        self.metallic = rec.addr_or_null(g.get(Channel::Metallic))?;
        self.ao = rec.addr_or_null(g.get(Channel::Ao))?;
        self.fixed_visibility = rec.addr_or_null(g.get(Channel::Visibility))?;
        self.editable_visibility = rec.addr_or_null(b.editable)?;
        self.alpha = rec.addr(&g.alpha)?;
        self.specular = rec.addr(&env.specular)?;
        self.irradiance = rec.addr(&env.irradiance)?;
        self.brdf = rec.addr(&b.inputs.brdf.buffer)?;
        self.l_sun = rec.addr(b.sun)?;
        self.l_sky = rec.addr(b.sky)?;
        self.l_ind = rec.addr_or_null(b.indirect)?;
        self.out_radiance = rec.addr(b.radiance)?;
        self.out_display = rec.addr(b.display)?;
        Ok(rec.update(uniform, 0, &self)?)
    }
}

#[cfg(test)]
mod layout_tests {
    use super::ShadeUniform;
    use crate::gpu::{check_layout, kernels};

    /// The host struct matches the `Shade` block of both shading kernels.
    #[test]
    fn uniform_layout_matches_glsl() {
        assert_eq!(check_layout::<ShadeUniform>(&[&kernels::SHADE_LIGHTS, &kernels::SHADE_COMPOSE]), Ok(2));
    }
}
