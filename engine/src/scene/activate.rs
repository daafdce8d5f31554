//! The scene on the GPU and its activation kernel.
//!
//! [`GpuScene`] holds the stored parameters in one storage buffer per
//! attribute, reached by device address so a scene of several million
//! Gaussians fits whatever the device's `maxStorageBufferRange`.
//! [`activate`] runs `scene_activate.comp`: opacity = σ(logit), scale = exp,
//! normalized quaternion, and the world covariance Σ = R S Sᵀ Rᵀ.
//! [`activate_cpu`] is its f64 CPU twin.

use std::sync::Arc;

use std::path::Path;

use super::layout::ActivatePush;
use super::{AttributeGroups, Bounds, Scene};
use crate::error::Result;
use crate::gpu::{kernels, Buffer, Device, Grid, Kernel, KernelDecl, MemoryKind, Timings};

/// A scene's stored parameters in GPU memory.
///
/// The per-Gaussian buffers hold their rows in device order: the file's (or
/// arrays') order unless [`GpuScene::arrange`] moved them, after which device
/// row `i` is file row [`RowOrder::to_file`](super::order::RowOrder::to_file)`[i]`
/// ([`GpuScene::row_order`]). Code that reads or writes the buffers
/// directly must map rows through it; [`GpuScene::download`] and
/// [`GpuScene::write_geometry`] already do.
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
    /// The rows' order when [`GpuScene::arrange`] moved them.
    row_order: Option<super::order::RowOrder>,
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
            row_order: None,
        })
    }

    /// Reads the scene file at `path` straight into GPU buffers: a PLY in
    /// blocks of about [`LOAD_BLOCK_BYTES`] of the file (each validated,
    /// written where it belongs, then reused for the next), so the host never
    /// holds the scene whole; any other format read whole, uploaded and
    /// dropped. Errors name the file and the row at fault; on one, nothing is
    /// kept. Returns what callers otherwise took from the host copy.
    pub fn load(device: &Device, path: impl AsRef<Path>) -> Result<LoadedScene> {
        Self::load_in_blocks(device, path, LOAD_BLOCK_BYTES)
    }

    /// [`GpuScene::load`] with blocks of about `block_bytes` of the file.
    pub fn load_in_blocks(device: &Device, path: impl AsRef<Path>, block_bytes: usize) -> Result<LoadedScene> {
        let mut loaded: Option<LoadedScene> = None;
        crate::io::read_scene_blocks(path, block_bytes, |block| {
            let part = block.gaussians;
            let bounds = part.bounds();
            let Some(l) = loaded.as_mut() else {
                // The first block sizes every buffer (a whole scene is its only block).
                let gpu = if block.total == part.len() {
                    Self::upload(device, part)?
                } else {
                    let gpu = Self::allocate(device, part, block.total)?;
                    gpu.write_rows(device, block.first, part)?;
                    gpu
                };
                loaded = Some(LoadedScene { gpu, attributes: part.attributes(), bounds });
                return Ok(());
            };
            l.gpu.write_rows(device, block.first, part)?;
            l.bounds = match (l.bounds, bounds) {
                (Some(a), Some(b)) => Some(a.union(&b)),
                (a, b) => a.or(b),
            };
            Ok(())
        })?;
        loaded.ok_or_else(|| crate::Error::Internal("a scene file gave no block".into()))
    }

    /// The scene back on the host, every attribute read from the device: for
    /// callers that loaded it straight to the device ([`GpuScene::load`]) and
    /// later need its arrays. Extra PLY properties are not kept on the device.
    pub fn download(&self, device: &Device) -> Result<Scene> {
        fn optional<T: bytemuck::Pod>(device: &Device, b: &Option<Buffer>) -> Result<Option<Vec<T>>> {
            Ok(b.as_ref().map(|b| device.read_buffer(b)).transpose()?)
        }
        let n = self.count;
        let k = super::sh_coefficients(self.sh_degree) * 3;
        let mut sh: Vec<f32> = device.read_buffer(&self.sh)?;
        sh.truncate(n * k);
        let mut scene = Scene {
            means: device.read_buffer(&self.means)?,
            log_scales: device.read_buffer(&self.log_scales)?,
            rotations: device.read_buffer(&self.rotations)?,
            opacity_logits: device.read_buffer(&self.opacity_logits)?,
            sh_degree: self.sh_degree,
            sh,
            normals: optional(device, &self.normals)?,
            materials: super::Materials {
                albedo: optional(device, &self.albedo)?,
                roughness: optional(device, &self.roughness)?,
                metallic: optional(device, &self.metallic)?,
                ao: optional(device, &self.ao)?,
                visibility: optional(device, &self.visibility)?,
            },
            ..Scene::default()
        };
        if scene.len() != n || scene.means.len() != n {
            return Err(crate::Error::Internal(format!("the scene's buffers hold {} Gaussians, not {n}", scene.len())));
        }
        if let Some(o) = &self.row_order {
            scene = scene.permuted(&o.to_device_indices());
        }
        Ok(scene)
    }

    /// Buffers for `total` Gaussians with `like`'s attributes, not yet written.
    fn allocate(device: &Device, like: &Scene, total: usize) -> Result<Self> {
        let n = total as u64;
        let make = |name: &str, floats: u64| device.create_buffer(name, floats * 4, MemoryKind::Storage);
        let optional = |on: bool, name: &str, floats: u64| on.then(|| make(name, floats)).transpose();
        let m = &like.materials;
        let k = super::sh_coefficients(like.sh_degree) as u64;
        Ok(Self {
            normals: optional(like.normals.is_some(), "scene normals", 3 * n)?,
            albedo: optional(m.albedo.is_some(), "scene albedo", 3 * n)?,
            roughness: optional(m.roughness.is_some(), "scene roughness", n)?,
            metallic: optional(m.metallic.is_some(), "scene metallic", n)?,
            ao: optional(m.ao.is_some(), "scene ao", n)?,
            visibility: optional(m.visibility.is_some(), "scene visibility", n)?,
            count: total,
            sh_degree: like.sh_degree,
            means: make("scene means", 3 * n)?,
            log_scales: make("scene log scales", 3 * n)?,
            rotations: make("scene rotations", 4 * n)?,
            opacity_logits: make("scene opacity logits", n)?,
            sh: make("scene SH", 3 * k * n)?,
            version: next_scene_version(),
            row_order: None,
        })
    }

    /// Writes `part`'s Gaussians as rows `first..` of every buffer.
    fn write_rows(&self, device: &Device, first: usize, part: &Scene) -> Result<()> {
        fn optional<T: bytemuck::Pod>(device: &Device, b: &Option<Buffer>, v: &Option<Vec<T>>, at: u64) -> Result<()> {
            if let (Some(b), Some(v)) = (b, v) {
                device.write_buffer(b, at * std::mem::size_of::<T>() as u64, v)?;
            }
            Ok(())
        }
        let at = first as u64;
        let k = super::sh_coefficients(self.sh_degree) as u64;
        let m = &part.materials;
        device.write_buffer(&self.means, at * 12, &part.means)?;
        device.write_buffer(&self.log_scales, at * 12, &part.log_scales)?;
        device.write_buffer(&self.rotations, at * 16, &part.rotations)?;
        device.write_buffer(&self.opacity_logits, at * 4, &part.opacity_logits)?;
        device.write_buffer(&self.sh, at * 12 * k, &part.sh)?;
        optional(device, &self.normals, &part.normals, at)?;
        optional(device, &self.albedo, &m.albedo, at)?;
        optional(device, &self.roughness, &m.roughness, at)?;
        optional(device, &self.metallic, &m.metallic, at)?;
        optional(device, &self.ao, &m.ao, at)?;
        optional(device, &self.visibility, &m.visibility, at)?;
        Ok(())
    }

    /// The rows' order on the device when [`GpuScene::arrange`] moved them
    /// (`None`: as listed in the file or arrays the scene came from).
    pub fn row_order(&self) -> Option<&super::order::RowOrder> {
        self.row_order.as_ref()
    }

    pub(super) fn set_row_order(&mut self, order: super::order::RowOrder) {
        self.row_order = Some(order);
        self.mark_changed();
    }

    /// Every buffer holding a row per Gaussian, with its row's length in words.
    pub(super) fn row_buffers(&self) -> Vec<(&Buffer, u32)> {
        let sh_words = 3 * super::sh_coefficients(self.sh_degree) as u32;
        let optional = [
            (&self.normals, 3),
            (&self.albedo, 3),
            (&self.roughness, 1),
            (&self.metallic, 1),
            (&self.ao, 1),
            (&self.visibility, 1),
        ];
        [(&self.means, 3), (&self.log_scales, 3), (&self.rotations, 4), (&self.opacity_logits, 1), (&self.sh, sh_words)]
            .into_iter()
            .chain(optional.into_iter().filter_map(|(b, w)| b.as_ref().map(|b| (b, w))))
            .collect()
    }

    /// Replaces every Gaussian's geometry (a training step), each array listed
    /// in file order: `means` and `log_scales` 3 floats a Gaussian,
    /// `rotations` 4 (w, x, y, z), `opacity_logits` 1. Lengths are checked
    /// before anything is written; the scene counts as changed
    /// ([`GpuScene::mark_changed`]) from the first write on.
    pub fn write_geometry(
        &mut self,
        device: &Device,
        means: &[f32],
        log_scales: &[f32],
        rotations: &[f32],
        opacity_logits: &[f32],
    ) -> Result<()> {
        let n = self.count;
        for (name, v, per) in [
            ("means", means, 3),
            ("log_scales", log_scales, 3),
            ("rotations", rotations, 4),
            ("opacity_logits", opacity_logits, 1),
        ] {
            if Some(v.len()) != n.checked_mul(per) {
                return Err(crate::Error::invalid(
                    format!("{name} of {} floats", v.len()),
                    format!("must hold {per} a Gaussian for the scene's {n}"),
                ));
            }
        }
        self.mark_changed();
        let arrays = [
            (&self.means, means, 3),
            (&self.log_scales, log_scales, 3),
            (&self.rotations, rotations, 4),
            (&self.opacity_logits, opacity_logits, 1),
        ];
        for (buffer, v, per) in arrays {
            match &self.row_order {
                Some(o) => device.write_buffer(buffer, 0, &o.rows_to_device(v, per))?,
                None => device.write_buffer(buffer, 0, v)?,
            }
        }
        Ok(())
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

/// Bytes of the file per block [`GpuScene::load`] reads and writes at a time.
pub const LOAD_BLOCK_BYTES: usize = 16 << 20;

/// A scene [`GpuScene::load`] read straight to the device, with what callers
/// otherwise take from a host copy.
pub struct LoadedScene {
    /// The Gaussians on the device.
    pub gpu: GpuScene,
    /// Which optional attribute groups the scene has.
    pub attributes: AttributeGroups,
    /// Bounds of the centres; `None` for an empty scene.
    pub bounds: Option<Bounds>,
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
