//! The shading pass: L_sun and L_sky per pixel, the indirect network when
//! one is given, then the composite and the display image.

use std::sync::Arc;

use bytemuck::Zeroable;

use super::*;
use crate::error::{Error, Result};
use crate::gpu::{kernels, Binding, Device, Grid, Kernel, KernelDecl, MemoryKind, SpecValue};
use crate::splat::Channel;

/// The shading kernels.
pub struct Shader {
    device: Device,
    compose: Arc<Kernel>,
}

impl Shader {
    /// Builds the compose kernel (light kernels are built per term set on first use).
    pub fn new(device: &Device) -> Result<Self> {
        Ok(Self { device: device.clone(), compose: device.kernel(&kernels::SHADE_COMPOSE, &KernelDecl::uniform(&[]))? })
    }

    /// The uniform for `inputs`; output addresses filled by the caller.
    /// The uniform (without addresses) and the visibility it settled on
    /// (none without a sun above the horizon).
    fn uniform(inputs: &ShadeInputs<'_>, settings: &ShadeSettings) -> Result<(ShadeUniform, VisibilitySource)> {
        settings.validate()?;
        let (g, camera) = (inputs.gbuffer, inputs.camera);
        if (g.width, g.height) != (camera.width, camera.height) {
            return Err(Error::invalid(
                format!("G-buffer {}x{}", g.width, g.height),
                format!("does not match camera {}x{}", camera.width, camera.height),
            ));
        }
        if g.get(Channel::Normal).is_none() || g.get(Channel::Albedo).is_none() {
            return Err(Error::invalid(
                "G-buffer",
                "lacks the normal and albedo channels shading needs (a scene without albedo renders plain colour, \
                 unshaded)",
            ));
        }
        let sun = inputs.sun.filter(|s| s.above_horizon());
        let mut visibility = settings.visibility;
        if sun.is_none() {
            visibility = VisibilitySource::None;
        }
        if visibility == VisibilitySource::Fixed && g.get(Channel::Visibility).is_none() {
            return Err(Error::invalid("fixed visibility", "needs the visibility G-buffer channel"));
        }
        let pixels = u64::from(g.width) * u64::from(g.height);
        if visibility == VisibilitySource::Editable {
            let v = inputs
                .editable_visibility
                .ok_or_else(|| Error::invalid("editable visibility", "needs the shadow pass's visibility buffer"))?;
            if v.size() < pixels * 4 {
                return Err(Error::invalid("editable visibility buffer", "is smaller than the image"));
            }
        }
        if let Some(ind) = inputs.indirect {
            if ind.size() < pixels * 12 {
                return Err(Error::invalid("indirect light buffer", "is smaller than the image"));
            }
        }
        let env = inputs.environment;
        let mut u = ShadeUniform::zeroed();
        u.camera = camera.packed().to_world;
        u.size = [g.width, g.height, env.levels, inputs.brdf.size];
        u.env_size = [env.base.0, env.base.1, env.irradiance_size.0, env.irradiance_size.1];
        if let Some(s) = sun {
            u.sun_dir = [s.direction.x, s.direction.y, s.direction.z, 1.0];
            u.sun_radiance = [s.intensity[0], s.intensity[1], s.intensity[2], 0.0];
        }
        let rho = f64::from(settings.env_rotation_degrees).to_radians();
        u.env = [rho.cos() as f32, rho.sin() as f32, settings.env_intensity, settings.min_alpha];
        u.background = match settings.background {
            Background::Environment => [0.0, 0.0, 0.0, 1.0],
            Background::Color(c) => [c[0], c[1], c[2], 0.0],
        };
        u.display = [2f32.powf(settings.exposure_ev), settings.tone_map.code() as f32, 0.0, 0.0];
        u.modes = [visibility.code(), 0, 0, 0];
        Ok((u, visibility))
    }

    /// Shades one frame: L_sun and L_sky, then the composite and display image.
    pub fn shade(&mut self, inputs: &ShadeInputs<'_>, settings: &ShadeSettings) -> Result<ShadedFrame> {
        self.shade_impl(inputs, settings, None)
    }

    /// Shades one frame with the indirect network: L_sun and L_sky, the
    /// network's L_ind from them and the G-buffers, then the composite.
    pub fn shade_with_network(
        &mut self,
        inputs: &ShadeInputs<'_>,
        settings: &ShadeSettings,
        network: &mut crate::indirect::UNet,
    ) -> Result<ShadedFrame> {
        if inputs.indirect.is_some() {
            return Err(Error::invalid("indirect light", "give either an L_ind buffer or a network, not both"));
        }
        self.shade_impl(inputs, settings, Some(network))
    }

    fn shade_impl(
        &mut self,
        inputs: &ShadeInputs<'_>,
        settings: &ShadeSettings,
        network: Option<&mut crate::indirect::UNet>,
    ) -> Result<ShadedFrame> {
        let (u, visibility) = Self::uniform(inputs, settings)?;
        let device = self.device.clone();
        let g = inputs.gbuffer;
        let pixels = u64::from(g.width) * u64::from(g.height);
        let make = |name: &str| device.create_buffer(name, pixels * 12, MemoryKind::Storage);
        let (sun, sky, radiance, display) = (make("L_sun")?, make("L_sky")?, make("radiance")?, make("display")?);
        let uniform =
            device.create_buffer("shade uniform", std::mem::size_of::<ShadeUniform>() as u64, MemoryKind::Storage)?;
        let editable = if visibility == VisibilitySource::Editable { inputs.editable_visibility } else { None };
        let bits = settings.terms.bits();
        let lights = device.kernel(&kernels::SHADE_LIGHTS, &KernelDecl::uniform(&[(0, SpecValue::U32(bits))]))?;
        let lights: &Kernel = &lights;
        let mut timings = device.run(|rec| -> Result<()> {
            let buffers = ShadeBuffers {
                inputs,
                editable,
                indirect: inputs.indirect,
                sun: &sun,
                sky: &sky,
                radiance: &radiance,
                display: &display,
            };
            u.record(rec, &uniform, &buffers)?;
            if let Some(word) = settings.prefill {
                for b in [&sun, &sky, &radiance, &display] {
                    rec.fill(b, word)?;
                }
            }
            rec.begin_stage("shade lights");
            rec.dispatch(lights, Grid::Items(pixels), &[Binding::from(&uniform)], &())?;
            rec.end_stage();
            Ok(())
        })?;
        let mut indirect = None;
        if let Some(net) = network {
            let inputs =
                crate::indirect::NetworkInputs { gbuffer: g, sun: &sun, sky: &sky, min_alpha: settings.min_alpha };
            let out = net.predict(&inputs)?;
            timings.stages.extend(out.timings.stages);
            indirect = Some(out.output);
        }
        let compose = &self.compose;
        let t = device.run(|rec| -> Result<()> {
            let buffers = ShadeBuffers {
                inputs,
                editable,
                indirect: indirect.as_ref().or(inputs.indirect),
                sun: &sun,
                sky: &sky,
                radiance: &radiance,
                display: &display,
            };
            u.record(rec, &uniform, &buffers)?;
            rec.begin_stage("shade compose");
            rec.dispatch(compose, Grid::Items(pixels), &[Binding::from(&uniform)], &())?;
            rec.end_stage();
            Ok(())
        })?;
        timings.stages.extend(t.stages);
        Ok(ShadedFrame { width: g.width, height: g.height, sun, sky, radiance, display, indirect, timings })
    }
}
