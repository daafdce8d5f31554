//! The scene on the GPU and its activation kernel.
//!
//! [`GpuScene`] holds the stored parameters in one storage buffer per
//! attribute, reached by device address so a scene of several million
//! Gaussians fits whatever the device's `maxStorageBufferRange`.
//! [`activate`] runs `scene_activate.comp`: opacity = σ(logit), scale = exp,
//! normalized quaternion, and the world covariance Σ = R S Sᵀ Rᵀ.
//! [`activate_cpu`] is its f64 CPU twin.

use std::sync::Arc;

use super::layout::ActivatePush;
use super::Scene;
use crate::error::Result;
use crate::gpu::{kernels, Buffer, Device, Grid, Kernel, KernelDecl, Timings};

/// A scene's stored parameters in GPU memory.
pub struct GpuScene {
    /// Number of Gaussians.
    pub count: usize,
    /// SH degree.
    pub sh_degree: u32,
    /// `float[3N]` centres.
    pub means: Buffer,
    /// `float[3N]` log scales.
    pub log_scales: Buffer,
    /// `float[4N]` quaternions (w, x, y, z).
    pub rotations: Buffer,
    /// `float[N]` opacity logits.
    pub opacity_logits: Buffer,
    /// float[3·K·N] SH coefficients, coefficient-major, RGB innermost.
    pub sh: Buffer,
    /// `float[3N]` stored normals, when the scene has them.
    pub normals: Option<Buffer>,
    /// `float[3N]` albedo logits, when present.
    pub albedo: Option<Buffer>,
    /// `float[N]` roughness logits, when present.
    pub roughness: Option<Buffer>,
    /// `float[N]` metallic logits, when present.
    pub metallic: Option<Buffer>,
    /// `float[N]` ambient-occlusion logits, when present.
    pub ao: Option<Buffer>,
    /// `float[N]` fixed-visibility logits, when present.
    pub visibility: Option<Buffer>,
    /// What [`GpuScene::version`] returns.
    version: u64,
}

/// The next [`GpuScene::version`] (process-wide, so no two uploads share one).
static NEXT_SCENE_VERSION: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);

fn next_scene_version() -> u64 {
    NEXT_SCENE_VERSION.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
}

impl GpuScene {
    /// Uploads the scene's parameters; optional groups only when present
    /// (their size is what [`Scene::gpu_bytes`] counts).
    pub fn upload(device: &Device, scene: &Scene) -> Result<Self> {
        fn optional<T: bytemuck::Pod>(device: &Device, name: &str, data: &Option<Vec<T>>) -> Result<Option<Buffer>> {
            Ok(data.as_ref().map(|v| device.upload(name, v)).transpose()?)
        }
        let m = &scene.materials;
        Ok(Self {
            normals: optional(device, "scene normals", &scene.normals)?,
            albedo: optional(device, "scene albedo", &m.albedo)?,
            roughness: optional(device, "scene roughness", &m.roughness)?,
            metallic: optional(device, "scene metallic", &m.metallic)?,
            ao: optional(device, "scene ao", &m.ao)?,
            visibility: optional(device, "scene visibility", &m.visibility)?,
            count: scene.len(),
            sh_degree: scene.sh_degree,
            means: device.upload("scene means", &scene.means)?,
            log_scales: device.upload("scene log scales", &scene.log_scales)?,
            rotations: device.upload("scene rotations", &scene.rotations)?,
            opacity_logits: device.upload("scene opacity logits", &scene.opacity_logits)?,
            sh: device.upload("scene SH", &scene.sh)?,
            version: next_scene_version(),
        })
    }

    /// Identifies this scene's contents: unique per upload, and renewed by
    /// [`GpuScene::mark_changed`]. Results derived from the Gaussians alone
    /// (a reused shadow map) are valid while it stays the same.
    pub fn version(&self) -> u64 {
        self.version
    }

    /// Records that the buffers' contents were changed in place (written
    /// after the upload), so results cached for the old contents are not reused.
    pub fn mark_changed(&mut self) {
        self.version = next_scene_version();
    }
}

/// Activated parameters on the GPU.
pub struct Activated {
    /// `float[6N]`: Σ as (xx, xy, xz, yy, yz, zz).
    pub covariances: Buffer,
    /// `float[N]` opacities in (0, 1).
    pub opacities: Buffer,
    /// GPU time of the kernel.
    pub timings: Timings,
}

/// Builds the activation kernel.
pub fn activate_kernel(device: &Device) -> Result<Arc<Kernel>> {
    Ok(device.kernel(&kernels::SCENE_ACTIVATE, &KernelDecl::push::<ActivatePush>(&[]))?)
}

/// Activates `scene` on the GPU. Outputs are pre-filled with NaN so an
/// element the kernel missed cannot pass for a value.
pub fn activate(device: &Device, kernel: &Kernel, scene: &GpuScene) -> Result<Activated> {
    const NAN: u32 = 0x7fc0_0000;
    let covariances = device.create_filled::<[f32; 6]>("activated covariances", scene.count, NAN)?;
    let opacities = device.create_filled::<f32>("activated opacities", scene.count, NAN)?;
    let timings = device.run(|rec| {
        let push = ActivatePush {
            log_scales: rec.addr(&scene.log_scales)?,
            rotations: rec.addr(&scene.rotations)?,
            opacity_logits: rec.addr(&scene.opacity_logits)?,
            covariances: rec.addr(&covariances)?,
            opacities: rec.addr(&opacities)?,
            count: scene.count as u32,
            pad: 0,
        };
        rec.begin_stage("activate");
        rec.dispatch(kernel, Grid::Items(scene.count as u64), &[], &push)
    })?;
    Ok(Activated { covariances, opacities, timings })
}

/// f64 CPU twin of `scene_activate.comp`: per Gaussian, (Σ as xx, xy, xz, yy, yz, zz; opacity).
pub fn activate_cpu(scene: &Scene) -> Vec<([f64; 6], f64)> {
    (0..scene.len())
        .map(|i| {
            let s = scene.log_scales[i].map(|v| f64::from(v).exp());
            let q = scene.rotations[i].map(f64::from);
            let norm = q.iter().map(|c| c * c).sum::<f64>().sqrt();
            let [w, x, y, z] = q.map(|c| c / norm);
            let r = [
                [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y)],
                [2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x)],
                [2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)],
            ];
            let cov = |a: usize, b: usize| (0..3).map(|k| r[a][k] * s[k] * s[k] * r[b][k]).sum::<f64>();
            let logit = f64::from(scene.opacity_logits[i]);
            ([cov(0, 0), cov(0, 1), cov(0, 2), cov(1, 1), cov(1, 2), cov(2, 2)], 1.0 / (1.0 + (-logit).exp()))
        })
        .collect()
}
