//! `srug bench shade`: deferred shading time per frame (the two shading
//! kernels on the demo city's G-buffers) per image size, and the one-time
//! environment preparation cost (pyramid, GGX prefilter, irradiance) per
//! environment size, plus the BRDF table. GPU timestamps, medians of repeats.

use super::median;
use srug::error::Result;
use srug::gpu::Device;
use srug::scene::activate::GpuScene;
use srug::scene::demo::{demo_city, DemoOptions};
use srug::shade::{
    BrdfLut, EnvironmentPrep, PrepareSettings, ProceduralSky, ShadeInputs, ShadeSettings, Shader, VisibilitySource,
};
use srug::shadow::Sun;
use srug::splat::{SplatSettings, Splatter};

/// Shading time at one image size.
#[derive(Clone, Debug)]
pub struct ShadeRow {
    /// Image size.
    pub size: (u32, u32),
    /// `shade lights` seconds (L_sun and L_sky).
    pub lights_seconds: f64,
    /// `shade compose` seconds.
    pub compose_seconds: f64,
}

/// Preparation time of one environment size.
#[derive(Clone, Debug)]
pub struct PrefilterRow {
    /// Environment size.
    pub size: (u32, u32),
    /// Prefiltered levels.
    pub levels: u32,
    /// Pyramid seconds.
    pub pyramid_seconds: f64,
    /// GGX prefilter seconds.
    pub prefilter_seconds: f64,
    /// Irradiance seconds.
    pub irradiance_seconds: f64,
    /// GPU bytes of the prepared environment.
    pub bytes: u64,
}

/// Everything `srug bench shade` measures.
pub struct ShadeBench {
    /// Per image size.
    pub shading: Vec<ShadeRow>,
    /// Per environment size.
    pub prefilter: Vec<PrefilterRow>,
    /// BRDF table seconds (129², 1024 samples) per variant.
    pub brdf_seconds: Vec<(BrdfLut, f64)>,
}

/// Runs the benchmark: the demo city with `gaussians`, shading at `sizes`,
/// preparation at `env_sizes` (procedural skies), `repeats` each.
pub fn shade_bench(
    device: &Device,
    gaussians: usize,
    sizes: &[(u32, u32)],
    env_sizes: &[(u32, u32)],
    repeats: usize,
    progress: impl Fn(&str),
) -> Result<ShadeBench> {
    let repeats = repeats.max(1);
    let sun = Sun::from_azimuth_elevation(260.0, 50.0, [std::f32::consts::PI; 3])?;
    let prep = EnvironmentPrep::new(device)?;
    let mut brdf_seconds = Vec::new();
    let mut table = None;
    for variant in [BrdfLut::Karis, BrdfLut::HeightCorrelated] {
        progress(&format!("BRDF table {variant:?}"));
        let mut t = Vec::new();
        for _ in 0..repeats {
            let b = prep.brdf_table(variant, 129, 1024)?;
            t.push(b.timings.total_seconds());
            table.get_or_insert(b);
        }
        brdf_seconds.push((variant, median(t)));
    }
    let mut prefilter = Vec::new();
    for &size in env_sizes {
        progress(&format!("prefiltering a {}x{} environment", size.0, size.1));
        let map = ProceduralSky { size, ..ProceduralSky::new(sun.direction, sun.intensity[0]) }.render()?;
        let (mut py, mut pf, mut ir) = (Vec::new(), Vec::new(), Vec::new());
        let mut last = None;
        for _ in 0..repeats {
            let p = prep.prepare(&map, &PrepareSettings::default())?;
            py.push(p.timings.get("environment pyramid").unwrap_or(f64::NAN));
            pf.push(p.timings.get("specular prefilter").unwrap_or(f64::NAN));
            ir.push(p.timings.get("irradiance").unwrap_or(f64::NAN));
            last = Some(p);
        }
        let (levels, bytes) = last.as_ref().map_or((0, 0), |p| (p.levels, p.bytes()));
        prefilter.push(PrefilterRow {
            size,
            levels,
            pyramid_seconds: median(py),
            prefilter_seconds: median(pf),
            irradiance_seconds: median(ir),
            bytes,
        });
    }
    progress(&format!("generating the demo city ({gaussians} Gaussians)"));
    let city = demo_city(&DemoOptions { gaussians, ..DemoOptions::default() })?;
    let scene = GpuScene::upload(device, &city.scene)?;
    let sky = ProceduralSky::new(sun.direction, sun.intensity[0]).render()?;
    let env = prep.prepare(&sky, &PrepareSettings::default())?;
    let brdf = table.ok_or_else(|| srug::Error::Internal("no BRDF table was prepared".into()))?;
    let mut splatter = Splatter::new(device)?;
    let mut shader = Shader::new(device)?;
    let settings = ShadeSettings { visibility: VisibilitySource::Fixed, ..ShadeSettings::default() };
    let mut shading = Vec::new();
    for &size in sizes {
        progress(&format!("shading {}x{}", size.0, size.1));
        let camera = city.cameras[0].resized(size.0, size.1);
        let channels = settings.gbuffer_channels(&city.scene.attributes());
        let (g, _) = splatter.render(&scene, &camera, &SplatSettings { channels, ..SplatSettings::default() })?;
        let (mut lights, mut compose) = (Vec::new(), Vec::new());
        for _ in 0..repeats {
            let inputs = ShadeInputs {
                gbuffer: &g,
                camera: &camera,
                environment: &env,
                brdf: &brdf,
                sun: Some(&sun),
                editable_visibility: None,
                indirect: None,
            };
            let f = shader.shade(&inputs, &settings)?;
            lights.push(f.timings.get("shade lights").unwrap_or(f64::NAN));
            compose.push(f.timings.get("shade compose").unwrap_or(f64::NAN));
        }
        shading.push(ShadeRow { size, lights_seconds: median(lights), compose_seconds: median(compose) });
    }
    Ok(ShadeBench { shading, prefilter, brdf_seconds })
}
