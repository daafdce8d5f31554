//! `srug._srug`: the native half of the `srug` Python package, PyO3 over the
//! Rust library (not over the C ABI). The pure-Python half
//! (`python/srug/__init__.py`) normalizes inputs (dtype, contiguity, shapes)
//! and names the API; this module does the work.
//!
//! Invariants: arrays cross as C-contiguous numpy float32 (uint32 for ids);
//! every output array is allocated once, filled straight from the GPU
//! readback's staging copy and handed to numpy without another copy; the GIL
//! is released while the GPU works (a progress callback re-acquires it); every
//! srug error becomes `srug.Error` with its message and a `kind`; no panic
//! crosses into Python (PyO3 turns one into `PanicException`, and nothing
//! here unwraps user input).

use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};

use glam::{Mat3, Vec3};
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use srug::camera::{Camera, Projection, DEFAULT_FAR, DEFAULT_NEAR};
use srug::frame::{HostDepthImage, Preset, RelightSettings, Relighter};
use srug::gpu::{Buffer, Device as GpuDevice, DeviceOptions, DeviceSelection};
use srug::scene::activate::GpuScene;
use srug::scene::order::SceneOrder;
use srug::scene::Scene as HostScene;
use srug::shade::{
    BrdfLut, BrdfTable, EnvironmentMap, EnvironmentPrep, PrepareSettings, PreparedEnvironment, ProceduralSky,
};
use srug::shadow::backward::GpuVisibilityLoss;
use srug::shadow::{ShadowMap, ShadowPass, ShadowSettings, Sun, VisibilityKind};
use srug::splat::{cameras_per_batch, Channel, Channels, SplatFrame, SplatSettings, Splatter, BATCH_BYTES};

create_exception!(
    srug,
    Error,
    PyException,
    "A srug error: the message says what and where; `kind` is one of invalid_argument, io, bad_file, \
     environment, gpu, internal."
);

/// The `kind` of a srug error.
fn kind(e: &srug::Error) -> &'static str {
    match e {
        srug::Error::Gpu(_) => "gpu",
        srug::Error::InvalidArgument { .. } => "invalid_argument",
        srug::Error::Internal(_) => "internal",
        srug::Error::Scene(_) => "bad_file",
        srug::Error::Environment { .. } => "environment",
        srug::Error::Io { .. } => "io",
    }
}

/// A srug error as `srug.Error` with its `kind`.
fn py_err(e: srug::Error) -> PyErr {
    let err = Error::new_err(e.to_string());
    Python::attach(|py| {
        // Setting an attribute on a fresh exception object cannot fail in practice; the message stays either way.
        let _ = err.value(py).setattr("kind", kind(&e));
    });
    err
}

/// `srug.Error` of kind invalid_argument.
fn invalid(what: impl Into<String>, why: impl Into<String>) -> PyErr {
    py_err(srug::Error::invalid(what, why))
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    // A panic while holding the lock leaves plain data behind: keep using it.
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// A float32 array's shape and values, checked to be finite; `what` names it in errors.
fn floats(a: &PyReadonlyArrayDyn<'_, f32>, what: &str) -> PyResult<(Vec<usize>, Vec<f32>)> {
    let values = a
        .as_slice()
        .map_err(|_| invalid(what.to_string(), "is not a C-contiguous array (np.ascontiguousarray makes one)"))?
        .to_vec();
    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        return Err(invalid(format!("{what} element {i}"), format!("is {} (values must be finite)", values[i])));
    }
    Ok((a.shape().to_vec(), values))
}

fn expect_shape(shape: &[usize], want: &[Option<usize>], what: &str) -> PyResult<()> {
    let ok = shape.len() == want.len() && shape.iter().zip(want).all(|(s, w)| w.is_none_or(|w| *s == w));
    if ok {
        return Ok(());
    }
    let text: Vec<String> = want.iter().map(|w| w.map_or("N".to_string(), |w| w.to_string())).collect();
    Err(invalid(format!("{what} of shape {shape:?}"), format!("must have shape ({})", text.join(", "))))
}

/// Values in [0, 1] as logits (clamped to [1e-6, 1 − 1e-6]) when `activated`, else as given.
fn logits(v: Vec<f32>, activated: bool, what: &str) -> PyResult<Vec<f32>> {
    if !activated {
        return Ok(v);
    }
    if let Some(i) = v.iter().position(|x| !(0.0..=1.0).contains(x)) {
        return Err(invalid(format!("{what} element {i}"), format!("is {} (activated values are 0 to 1)", v[i])));
    }
    Ok(v.iter().map(|x| x.clamp(1e-6, 1.0 - 1e-6)).map(|x| (x / (1.0 - x)).ln()).collect())
}

/// A point as Python receives it.
type Point = (f32, f32, f32);

static NEXT_DEVICE: AtomicU64 = AtomicU64::new(1);

/// Shadow options of `relight` that override the preset's (None: the preset's).
#[derive(Clone, Debug, Default)]
struct ShadowOptions {
    resolution: Option<u32>,
    k: Option<f32>,
    bias: Option<f32>,
    slope_bias: Option<f32>,
    normal_offset: Option<f32>,
    receiver_depth: Option<String>,
    test: Option<String>,
    filter: Option<String>,
    cascades: Option<u32>,
    map_coverage: Option<f32>,
    receiver_coverage: Option<f32>,
}

impl ShadowOptions {
    /// Overrides `settings`' shadow with the options given.
    fn apply(&self, settings: &mut RelightSettings) -> PyResult<()> {
        let s = &mut settings.shadow;
        s.resolution = self.resolution.unwrap_or(s.resolution);
        s.k = self.k.unwrap_or(s.k);
        s.bias = self.bias.unwrap_or(s.bias);
        s.slope_bias = self.slope_bias.unwrap_or(s.slope_bias);
        s.normal_offset = self.normal_offset.unwrap_or(s.normal_offset);
        s.cascades = self.cascades.unwrap_or(s.cascades);
        s.map_coverage = self.map_coverage.unwrap_or(s.map_coverage);
        s.receiver_coverage = self.receiver_coverage.unwrap_or(s.receiver_coverage);
        if let Some(d) = &self.receiver_depth {
            s.receiver_depth = srug::shadow::DepthMode::parse(d).map_err(py_err)?;
        }
        if let Some(f) = &self.filter {
            s.filter = srug::shadow::ShadowFilter::parse(f).map_err(py_err)?;
        }
        settings.visibility_kind = match self.test.as_deref() {
            None => settings.visibility_kind,
            Some("sigmoid") => VisibilityKind::Sigmoid,
            Some("traced") => VisibilityKind::Traced,
            Some(other) => return Err(invalid(format!("shadow test \"{other}\""), "is not sigmoid or traced")),
        };
        Ok(())
    }
}

/// What relighting keeps between calls: the relighter's kernels, the
/// environment preparation, the BRDF table, the last environments and the
/// last shadow map (reused while the scene, the sun's direction and the map
/// settings stay; a Python scene's arrays never change in place).
struct RelightKit {
    relighter: Relighter,
    prep: EnvironmentPrep,
    brdf: BrdfTable,
    /// The procedural sky for (sun direction, intensity) as bits.
    sky: Option<([u32; 4], PreparedEnvironment)>,
    /// The last environment file and its preparation.
    file: Option<(PathBuf, PreparedEnvironment)>,
}

impl RelightKit {
    fn new(device: &GpuDevice) -> srug::Result<Self> {
        let prep = EnvironmentPrep::new(device)?;
        let brdf = prep.brdf_table(BrdfLut::default(), 129, 1024)?;
        let mut relighter = Relighter::new(device)?;
        relighter.set_shadow_map_reuse(true);
        Ok(Self { relighter, prep, brdf, sky: None, file: None })
    }

    /// The environment: a map file or prepared folder, else the procedural sky of the sun.
    fn environment(&mut self, device: &GpuDevice, file: Option<&PathBuf>, sun: Option<&Sun>) -> srug::Result<()> {
        match file {
            Some(path) => {
                if self.file.as_ref().is_none_or(|(p, _)| p != path) {
                    let prepared = if path.is_dir() {
                        PreparedEnvironment::load(device, path)?
                    } else {
                        self.prep.prepare(&EnvironmentMap::load(path)?, &PrepareSettings::default())?
                    };
                    self.file = Some((path.clone(), prepared));
                }
            }
            None => {
                // Without a sun the sky is made for one 10° below the horizon (dusk), as the C ABI does.
                let (dir, power) = sun.map_or((Vec3::new(0.0, 0.985, -0.174), 1.0), |s| (s.direction, s.intensity[0]));
                let key = [dir.x, dir.y, dir.z, power].map(f32::to_bits);
                if self.sky.as_ref().is_none_or(|(k, _)| *k != key) {
                    let sky = ProceduralSky::new(dir, power).render()?;
                    self.sky = Some((key, self.prep.prepare(&sky, &PrepareSettings::default())?));
                }
            }
        }
        Ok(())
    }
}

/// A Vulkan device with srug's kernels: renders and relights batches of cameras.
///
/// `Device(device=None, validation=None)`: `device` as the CLI's `--device`
/// (an index from `srug devices`, "gpu", "cpu", or part of a name; None:
/// `SRUG_DEVICE`, else automatic); `validation` runs the Khronos validation
/// layer (None: `SRUG_VALIDATION`). Calls from several threads run at once,
/// each with its own kernels' state.
#[pyclass(frozen, module = "srug._srug")]
struct Device {
    id: u64,
    /// None once closed.
    device: Mutex<Option<GpuDevice>>,
    splatters: Mutex<Vec<Splatter>>,
    relighters: Mutex<Vec<RelightKit>>,
    /// Per-camera stage timings (name, milliseconds) of the last render or relight.
    timings: Mutex<Vec<Vec<(String, f64)>>>,
}

/// Where outputs go: one float32 array per channel, allocated once for the batch.
struct Outputs {
    arrays: Vec<(String, Vec<usize>, Output)>,
}

enum Output {
    F32(Vec<f32>),
    U32(Vec<u32>),
}

impl Outputs {
    fn slot_f32(&mut self, name: &str, index: usize) -> Option<&mut [f32]> {
        let (_, shape, out) = self.arrays.iter_mut().find(|(n, ..)| n == name)?;
        let len = shape[1..].iter().product::<usize>();
        match out {
            Output::F32(v) => v.get_mut(index * len..(index + 1) * len),
            Output::U32(_) => None,
        }
    }

    fn slot_u32(&mut self, name: &str, index: usize) -> Option<&mut [u32]> {
        let (_, shape, out) = self.arrays.iter_mut().find(|(n, ..)| n == name)?;
        let len = shape[1..].iter().product::<usize>();
        match out {
            Output::U32(v) => v.get_mut(index * len..(index + 1) * len),
            Output::F32(_) => None,
        }
    }

    /// Hands the arrays to numpy (no copy) as a dict name → array.
    fn into_dict(self, py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
        let dict = PyDict::new(py);
        for (name, shape, out) in self.arrays {
            let array = match out {
                Output::F32(v) => PyArray1::from_vec(py, v).reshape(shape)?.into_any(),
                Output::U32(v) => PyArray1::from_vec(py, v).reshape(shape)?.into_any(),
            };
            dict.set_item(name, array)?;
        }
        Ok(dict)
    }
}

/// The host's depth given to `render`/`relight`: one (H, W) image for every
/// camera or (N, H, W), one per camera, in `convention`; its values, whether
/// one image serves all, and the convention.
fn host_depth_values(
    array: Option<PyReadonlyArrayDyn<'_, f32>>,
    convention: &str,
    near: f32,
    far: f32,
    n: usize,
    w: u32,
    h: u32,
) -> PyResult<Option<(Vec<f32>, bool, srug::splat::HostDepth)>> {
    let Some(a) = array else { return Ok(None) };
    let convention = match convention {
        "camera_z" => srug::splat::HostDepth::CameraZ,
        "vulkan" => srug::splat::HostDepth::Vulkan { near, far },
        "reversed_z" => srug::splat::HostDepth::ReversedZ { near, far },
        other => {
            return Err(invalid(
                format!("depth convention \"{other}\""),
                "is not \"camera_z\", \"vulkan\" or \"reversed_z\"",
            ))
        }
    };
    convention.validate().map_err(py_err)?;
    let shape = a.shape().to_vec();
    let (hh, ww) = (h as usize, w as usize);
    if shape != [n, hh, ww] && shape != [hh, ww] {
        return Err(invalid(
            format!("host_depth of shape {shape:?}"),
            format!("must be ({n}, {hh}, {ww}) or ({hh}, {ww})"),
        ));
    }
    let values: Vec<f32> = a.as_array().iter().copied().collect();
    if let Some(i) = values.iter().position(|v| v.is_nan()) {
        return Err(invalid(format!("host_depth value {i}"), "is NaN"));
    }
    Ok(Some((values, shape.len() == 2, convention)))
}

/// One size for the whole batch (stacked outputs), or an error naming the first camera that differs.
fn batch_size(cameras: &[Camera]) -> PyResult<(u32, u32)> {
    let first = cameras.first().ok_or_else(|| invalid("cameras", "is empty"))?;
    if let Some((i, c)) = cameras.iter().enumerate().find(|(_, c)| (c.width, c.height) != (first.width, first.height)) {
        return Err(invalid(
            format!("camera {i} (\"{}\", {}x{})", c.name, c.width, c.height),
            format!(
                "differs in size from camera 0 ({}x{}); a batch is stacked into one array: resize the cameras \
                 (Cameras.resized) or render them in separate calls",
                first.width, first.height
            ),
        ));
    }
    Ok((first.width, first.height))
}

/// Calls the progress callback with (done, total) under the GIL.
fn report(progress: Option<&Py<PyAny>>, done: usize, total: usize) -> PyResult<()> {
    match progress {
        Some(cb) => Python::attach(|py| cb.call1(py, (done, total)).map(|_| ())),
        None => Ok(()),
    }
}

fn read_into(device: &GpuDevice, buffer: &Buffer, out: Option<&mut [f32]>) -> PyResult<()> {
    match out {
        Some(dst) => device.read_buffer_into(buffer, dst).map_err(|e| py_err(e.into())),
        None => Ok(()),
    }
}

impl Device {
    /// The Vulkan device, or an error once closed.
    fn gpu(&self) -> PyResult<GpuDevice> {
        lock(&self.device).clone().ok_or_else(|| invalid("device", "is closed"))
    }

    fn take_splatter(&self, device: &GpuDevice) -> srug::Result<Splatter> {
        match lock(&self.splatters).pop() {
            Some(s) => Ok(s),
            None => Splatter::new(device),
        }
    }

    fn take_relighter(&self, device: &GpuDevice) -> srug::Result<RelightKit> {
        match lock(&self.relighters).pop() {
            Some(k) => Ok(k),
            None => RelightKit::new(device),
        }
    }
}

#[pymethods]
impl Device {
    #[new]
    #[pyo3(signature = (device = None, validation = None))]
    fn new(py: Python<'_>, device: Option<String>, validation: Option<bool>) -> PyResult<Self> {
        let options = DeviceOptions { selection: device.as_deref().map(DeviceSelection::parse), validation };
        let device = py.detach(|| GpuDevice::new(&options)).map_err(|e| py_err(e.into()))?;
        Ok(Self {
            id: NEXT_DEVICE.fetch_add(1, Ordering::Relaxed),
            device: Mutex::new(Some(device)),
            splatters: Mutex::new(Vec::new()),
            relighters: Mutex::new(Vec::new()),
            timings: Mutex::new(Vec::new()),
        })
    }

    /// The device's name as its driver reports it.
    #[getter]
    fn name(&self) -> PyResult<String> {
        Ok(self.gpu()?.info().name.clone())
    }

    /// Whether the Khronos validation layer runs.
    #[getter]
    fn validation(&self) -> PyResult<bool> {
        Ok(self.gpu()?.validation_enabled())
    }

    /// Takes the validation layer's messages so far (empty when it is quiet or off).
    fn take_validation_messages(&self) -> PyResult<Vec<String>> {
        Ok(self.gpu()?.take_validation_messages())
    }

    /// Releases the device: its kernels and working memory now, the Vulkan
    /// device once the scenes uploaded to it are gone too. Later calls raise
    /// `srug.Error`; closing twice is harmless.
    fn close(&self) {
        lock(&self.splatters).clear();
        lock(&self.relighters).clear();
        *lock(&self.device) = None;
    }

    /// Whether `close` was called.
    #[getter]
    fn closed(&self) -> bool {
        lock(&self.device).is_none()
    }

    /// GPU memory srug holds on this device: {"current_bytes": …, "peak_bytes": …,
    /// "pooled_bytes": … (freed buffers kept for reuse), "fresh_allocations": …}.
    fn memory<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let m = self.gpu()?.memory_usage();
        let d = PyDict::new(py);
        d.set_item("current_bytes", m.current_bytes)?;
        d.set_item("peak_bytes", m.peak_bytes)?;
        d.set_item("pooled_bytes", m.pooled_bytes)?;
        d.set_item("fresh_allocations", m.fresh_allocations)?;
        Ok(d)
    }

    /// Frees the buffers kept for reuse (`memory()["pooled_bytes"]`) and
    /// returns how many bytes that released: for a host that wants the
    /// memory back between bursts of work.
    fn release_pooled_memory(&self) -> PyResult<u64> {
        Ok(self.gpu()?.release_pooled_memory())
    }

    /// Per-camera GPU stage times of the last render or relight: a list (one per
    /// camera) of lists of (stage name, milliseconds).
    fn last_timings(&self) -> Vec<Vec<(String, f64)>> {
        lock(&self.timings).clone()
    }

    /// Reads a scene file (any format srug reads, detected from the content)
    /// straight onto this device: a binary PLY streams in blocks, so the host
    /// never holds the whole scene (its arrays are read back from the device
    /// if `Scene.arrays`, `save` or another device asks for them). `order`:
    /// where its Gaussians go on the device, "auto" (along a Morton curve when
    /// the file lists them in no spatial order, as trained scenes do: faster
    /// frames, the same image), "morton" or "file"; ids, arrays and gradients
    /// stay in file order whatever the device's.
    #[pyo3(signature = (path, order = "auto"))]
    fn load_scene(&self, py: Python<'_>, path: PathBuf, order: &str) -> PyResult<Scene> {
        let device = self.gpu()?;
        let order = SceneOrder::parse(order).map_err(py_err)?;
        let loaded = py
            .detach(|| -> srug::Result<_> {
                let mut loaded = GpuScene::load(&device, &path)?;
                loaded.gpu.arrange(&device, order)?;
                Ok(loaded)
            })
            .map_err(py_err)?;
        let info = SceneInfo {
            count: loaded.gpu.count,
            sh_degree: loaded.gpu.sh_degree,
            attributes: loaded.attributes,
            bounds: loaded.bounds,
        };
        let uploads = Mutex::new(vec![(self.id, Arc::new(loaded.gpu), device)]);
        Ok(Scene { host: Mutex::new(None), info, uploads, order })
    }

    /// Renders every camera of `cameras` into G-buffer channels, stacked:
    /// a dict name → array, (N, H, W, C) float32 for colour-like channels,
    /// (N, H, W) for one-float ones, uint32 for "top_gaussian".
    #[pyo3(signature = (scene, cameras, channels, background = (0.0, 0.0, 0.0), sh_degree = None, tile = 16, progress = None,
                        surface_depth = false, host_depth = None, depth_convention = "camera_z", near = 0.0,
                        far = 0.0, median_coverage = 0.5))]
    #[allow(clippy::too_many_arguments, reason = "the Python keyword arguments of one call")]
    fn render<'py>(
        &self,
        py: Python<'py>,
        scene: &Scene,
        cameras: &Cameras,
        channels: Vec<String>,
        background: (f32, f32, f32),
        sh_degree: Option<u32>,
        tile: u32,
        progress: Option<Py<PyAny>>,
        surface_depth: bool,
        host_depth: Option<PyReadonlyArrayDyn<'py, f32>>,
        depth_convention: &str,
        near: f32,
        far: f32,
        median_coverage: f32,
    ) -> PyResult<Bound<'py, PyDict>> {
        let device = self.gpu()?;
        let cams = &cameras.cameras;
        let (w, h) = batch_size(cams)?;
        let host = host_depth_values(host_depth, depth_convention, near, far, cams.len(), w, h)?;
        let blended: Vec<&str> = channels.iter().map(String::as_str).filter(|c| *c != "range").collect();
        let mut set = Channels::parse(&blended.join(",")).map_err(py_err)?;
        let rgb = channels.iter().any(|c| c == "rgb" || c == "all");
        let range = channels.iter().any(|c| c == "range");
        if let Some(c) = channels.iter().find(|c| c.contains(',')) {
            return Err(invalid(format!("channel \"{c}\""), "is a list: give one name per item"));
        }
        // "range" is depth times each pixel's ray length per unit depth: it needs the depth channel.
        let wants_depth = set.depth;
        set.depth |= range;
        let settings = SplatSettings {
            background: [background.0, background.1, background.2],
            channels: set,
            rgb,
            sh_degree,
            tile,
            surface_depth,
            median_coverage,
            ..SplatSettings::default()
        };
        let (n, p) = (cams.len(), (w as usize) * (h as usize));
        let mut arrays = Vec::new();
        let mut add = |name: &str, k: usize, ids: bool| {
            let mut shape = vec![n, h as usize, w as usize];
            if k > 1 {
                shape.push(k);
            }
            let out = if ids { Output::U32(vec![u32::MAX; n * p]) } else { Output::F32(vec![0.0; n * p * k]) };
            arrays.push((name.to_string(), shape, out));
        };
        if rgb {
            add("rgb", 3, false);
        }
        add("alpha", 1, false);
        for c in set.iter().filter(|c| *c != Channel::Depth || wants_depth) {
            add(c.name(), c.floats(), false);
        }
        if set.top_gaussian {
            add("top_gaussian", 1, true);
        }
        if range {
            add("range", 1, false);
        }
        let mut outputs = Outputs { arrays };
        let gpu_scene = py.detach(|| scene.gpu(self.id, &device)).map_err(py_err)?;
        let progress = progress.as_ref();
        let timings = py.detach(|| -> PyResult<Vec<Vec<(String, f64)>>> {
            let mut splatter = self.take_splatter(&device).map_err(py_err)?;
            let mut timings = Vec::with_capacity(n);
            let mut depth_scratch = if range && !wants_depth { vec![0.0f32; p] } else { Vec::new() };
            let result = (|| -> PyResult<()> {
                // Without a host depth, cameras in batches: one submission per step for each.
                let batch = cams
                    .first()
                    .map_or(1, |cam| cameras_per_batch(gpu_scene.count as u64, cam, &settings, BATCH_BYTES));
                let mut i = 0;
                while i < n {
                    let frames = match &host {
                        None => splatter.render_batch(&gpu_scene, &cams[i..(i + batch).min(n)], &settings),
                        Some((values, shared, convention)) => {
                            let slice = if *shared { &values[..] } else { &values[i * p..(i + 1) * p] };
                            let depth = device.upload("host depth", slice).map_err(|e| py_err(e.into()))?;
                            splatter
                                .render_frame_occluded(&gpu_scene, &cams[i], &settings, &depth, *convention)
                                .map(|frame| vec![(frame.gbuffer, frame.stats)])
                        }
                    }
                    .map_err(py_err)?;
                    for (g, stats) in frames {
                        let cam = &cams[i];
                        let d = &device;
                        read_into(d, &g.alpha, outputs.slot_f32("alpha", i))?;
                        if let Some(b) = &g.rgb {
                            read_into(d, b, outputs.slot_f32("rgb", i))?;
                        }
                        for c in set.iter() {
                            let Some(b) = g.get(c) else { continue };
                            if c == Channel::Depth && !wants_depth {
                                read_into(d, b, Some(&mut depth_scratch))?;
                            } else {
                                read_into(d, b, outputs.slot_f32(c.name(), i))?;
                            }
                        }
                        if let (Some(b), Some(dst)) = (&g.top_gaussian, outputs.slot_u32("top_gaussian", i)) {
                            d.read_buffer_into(b, dst).map_err(|e| py_err(e.into()))?;
                        }
                        if range {
                            let depth: Vec<f32> = match outputs.slot_f32("depth", i) {
                                Some(v) => v.to_vec(),
                                None => depth_scratch.clone(),
                            };
                            if let Some(dst) = outputs.slot_f32("range", i) {
                                for (px, (r, z)) in dst.iter_mut().zip(&depth).enumerate() {
                                    let centre = [(px % w as usize) as f64 + 0.5, (px / w as usize) as f64 + 0.5];
                                    *r = cam.ray_length_per_depth(centre).map_or(0.0, |s| (f64::from(*z) * s) as f32);
                                }
                            }
                        }
                        timings.push(stats.timings.stages.iter().map(|s| (s.name.clone(), s.seconds * 1e3)).collect());
                        report(progress, i + 1, n)?;
                        i += 1;
                    }
                }
                Ok(())
            })();
            lock(&self.splatters).push(splatter);
            result.map(|()| timings)
        })?;
        *lock(&self.timings) = timings;
        outputs.into_dict(py)
    }

    /// Relights every camera of `cameras` (the scene needs an albedo
    /// attribute) and returns (N, H, W, 3) float32: linear radiance over the
    /// background (`output="radiance"`) or display values in [0, 1] after
    /// exposure, tone map and sRGB (`output="display"`).
    #[pyo3(signature = (scene, cameras, sun = None, sun_intensity = std::f32::consts::PI, preset = "balanced",
                        environment = None, env_rotation = 0.0, env_intensity = 1.0, exposure = 0.0,
                        output = "radiance", progress = None, surface_depth = None, shadow_fit = "scene",
                        host_depth = None, depth_convention = "camera_z", near = 0.0, far = 0.0, background = None,
                        shadow_cull = false, shadow_resolution = None, shadow_k = None, shadow_bias = None,
                        shadow_slope_bias = None, shadow_normal_offset = None, receiver_depth = None,
                        shadow_test = None, shadow_filter = None, shadow_cascades = None,
                        map_surface_depth = None, map_coverage = None, receiver_coverage = None))]
    #[allow(clippy::too_many_arguments, reason = "the Python keyword arguments of one call")]
    fn relight<'py>(
        &self,
        py: Python<'py>,
        scene: &Scene,
        cameras: &Cameras,
        sun: Option<(f32, f32)>,
        sun_intensity: f32,
        preset: &str,
        environment: Option<PathBuf>,
        env_rotation: f32,
        env_intensity: f32,
        exposure: f32,
        output: &str,
        progress: Option<Py<PyAny>>,
        surface_depth: Option<bool>,
        shadow_fit: &str,
        host_depth: Option<PyReadonlyArrayDyn<'py, f32>>,
        depth_convention: &str,
        near: f32,
        far: f32,
        background: Option<(f32, f32, f32)>,
        shadow_cull: bool,
        shadow_resolution: Option<u32>,
        shadow_k: Option<f32>,
        shadow_bias: Option<f32>,
        shadow_slope_bias: Option<f32>,
        shadow_normal_offset: Option<f32>,
        receiver_depth: Option<String>,
        shadow_test: Option<String>,
        shadow_filter: Option<String>,
        shadow_cascades: Option<u32>,
        map_surface_depth: Option<bool>,
        map_coverage: Option<f32>,
        receiver_coverage: Option<f32>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let shadow = ShadowOptions {
            resolution: shadow_resolution,
            k: shadow_k,
            bias: shadow_bias,
            slope_bias: shadow_slope_bias,
            normal_offset: shadow_normal_offset,
            receiver_depth,
            test: shadow_test,
            filter: shadow_filter,
            cascades: shadow_cascades,
            map_coverage,
            receiver_coverage,
        };
        let device = self.gpu()?;
        let cams = &cameras.cameras;
        let (w, h) = batch_size(cams)?;
        let host = host_depth_values(host_depth, depth_convention, near, far, cams.len(), w, h)?;
        let display = match output {
            "radiance" => false,
            "display" => true,
            other => return Err(invalid(format!("output \"{other}\""), "is not \"radiance\" or \"display\"")),
        };
        let sun = sun
            .map(|(azimuth, elevation)| Sun::from_azimuth_elevation(azimuth, elevation, [sun_intensity; 3]))
            .transpose()
            .map_err(py_err)?;
        let mut settings = RelightSettings::preset(Preset::parse(preset).map_err(py_err)?);
        settings.shade.exposure_ev = exposure;
        settings.shade.env_rotation_degrees = env_rotation;
        settings.shade.env_intensity = env_intensity;
        settings.shadow.surface_depth = surface_depth.unwrap_or(settings.shadow.surface_depth);
        settings.shadow.map_surface_depth = map_surface_depth.unwrap_or(settings.shadow.map_surface_depth);
        settings.shadow.fit = srug::shadow::ShadowFit::parse(shadow_fit).map_err(py_err)?;
        settings.shadow.cull_to_receivers = shadow_cull;
        shadow.apply(&mut settings)?;
        if let Some((r, g, b)) = background {
            settings.shade.background = srug::shade::Background::Color([r, g, b]);
        }
        settings.validate().map_err(py_err)?;
        // The host's depth is per pixel of the frame as rendered: a reduced render scale has other pixels.
        if host.is_some() && cams.first().is_some_and(|c| settings.render_size(c.width, c.height) != (w, h)) {
            return Err(invalid(
                format!("host_depth with preset \"{preset}\""),
                "needs frames rendered at the camera's size (the fast preset renders at half size: use balanced or reference)",
            ));
        }
        let attributes = scene.info.attributes;
        if !attributes.shadeable() {
            return Err(invalid("scene", "has no albedo attribute, so it cannot be relit; render its colour instead"));
        }
        let bounds = scene.info.bounds.ok_or_else(|| invalid("scene", "is empty"))?;
        let (n, p) = (cams.len(), (w as usize) * (h as usize));
        let name = if display { "display" } else { "radiance" };
        let mut outputs = Outputs {
            arrays: vec![
                (name.to_string(), vec![n, h as usize, w as usize, 3], Output::F32(vec![0.0; n * p * 3])),
                ("alpha".to_string(), vec![n, h as usize, w as usize], Output::F32(vec![0.0; n * p])),
            ],
        };
        let gpu_scene = py.detach(|| scene.gpu(self.id, &device)).map_err(py_err)?;
        let progress = progress.as_ref();
        let timings = py.detach(|| -> PyResult<Vec<Vec<(String, f64)>>> {
            let mut kit = self.take_relighter(&device).map_err(py_err)?;
            let mut timings = Vec::with_capacity(n);
            let result = (|| -> PyResult<()> {
                kit.environment(&device, environment.as_ref(), sun.as_ref()).map_err(py_err)?;
                let RelightKit { relighter, brdf, sky, file, .. } = &mut kit;
                let env = match (&environment, file.as_ref(), sky.as_ref()) {
                    (Some(_), Some((_, e)), _) | (None, _, Some((_, e))) => e,
                    _ => return Err(py_err(srug::Error::Internal("no environment was prepared".into()))),
                };
                // Cameras in batches: their splats one submission per step.
                let estimate = SplatSettings { channels: Channels::ALL, ..SplatSettings::default() };
                let batch = cams
                    .first()
                    .map_or(1, |cam| cameras_per_batch(gpu_scene.count as u64, cam, &estimate, BATCH_BYTES));
                let mut frames = Vec::new().into_iter();
                for i in 0..n {
                    if frames.len() == 0 {
                        // With a host depth, one camera at a time (its own depth image, unless shared).
                        let end = if host.is_some() { i + 1 } else { (i + batch).min(n) };
                        if let Some((values, shared, convention)) = &host {
                            let slice = if *shared { &values[..] } else { &values[i * p..(i + 1) * p] };
                            let buffer = device.upload("host depth", slice).map_err(|e| py_err(e.into()))?;
                            let image = HostDepthImage { buffer, width: w, height: h, convention: *convention };
                            relighter.set_host_depth(Some(image)).map_err(py_err)?;
                        }
                        let chunk = &cams[i..end];
                        let relit = relighter.render_batch(
                            &gpu_scene,
                            &attributes,
                            &bounds,
                            chunk,
                            sun.as_ref(),
                            env,
                            brdf,
                            &settings,
                        );
                        frames = relit.map_err(py_err)?.into_iter();
                    }
                    let relit =
                        frames.next().ok_or_else(|| py_err(srug::Error::Internal("a batch ran short".into())))?;
                    let dst = outputs.slot_f32(name, i);
                    if (relit.shaded.width, relit.shaded.height) == (w, h) {
                        let buffer = if display { &relit.shaded.display } else { &relit.shaded.radiance };
                        read_into(&device, buffer, dst)?;
                    } else {
                        // A reduced render scale: brought back to the camera's size.
                        let image = relit.shaded.read(&device).and_then(|s| s.resampled(w, h)).map_err(py_err)?;
                        if let Some(dst) = dst {
                            dst.copy_from_slice(if display { &image.display } else { &image.radiance });
                        }
                    }
                    let alpha = outputs.slot_f32("alpha", i);
                    if (relit.gbuffer.width, relit.gbuffer.height) == (w, h) {
                        read_into(&device, &relit.gbuffer.alpha, alpha)?;
                    } else if let Some(dst) = alpha {
                        let size = (relit.gbuffer.width, relit.gbuffer.height);
                        let v: Vec<f32> = device.read_buffer(&relit.gbuffer.alpha).map_err(|e| py_err(e.into()))?;
                        dst.copy_from_slice(&srug::image::resample_bilinear(&v, size, 1, (w, h)).map_err(py_err)?);
                    }
                    timings.push(relit.timings.stages.iter().map(|s| (s.name.clone(), s.seconds * 1e3)).collect());
                    report(progress, i + 1, n)?;
                }
                Ok(())
            })();
            // The relighter is kept for later calls: without this call's host depth.
            let reset = kit.relighter.set_host_depth(None).map_err(py_err);
            let result = result.and(reset);
            lock(&self.relighters).push(kit);
            result.map(|()| timings)
        })?;
        *lock(&self.timings) = timings;
        outputs.into_dict(py)
    }

    /// The differentiable sun shadow test for one camera (the paper's editable
    /// visibility V_e): renders the receivers, splats the shadow map from the
    /// sun and tests every pixel, V = sigmoid(k·(z_s − z + bias)), 1 where no
    /// receiver. The returned object holds V and runs the backward pass.
    #[pyo3(signature = (scene, camera, sun, resolution = 2048, k = 50.0, bias = 0.8, map_depth = None,
                        receiver_depth = None, sun_intensity = std::f32::consts::PI, slope_bias = 3.0,
                        normal_offset = 0.0, fit = "scene", tile = 16, filter = "pcf", surface_depth = true,
                        map_surface_depth = false, map_coverage = None, receiver_coverage = None))]
    #[allow(clippy::too_many_arguments, reason = "the Python keyword arguments of one call")]
    fn shadow(
        &self,
        py: Python<'_>,
        scene: &Scene,
        camera: &Cameras,
        sun: (f32, f32),
        resolution: u32,
        k: f32,
        bias: f32,
        map_depth: Option<&str>,
        receiver_depth: Option<&str>,
        sun_intensity: f32,
        slope_bias: f32,
        normal_offset: f32,
        fit: &str,
        tile: u32,
        filter: &str,
        surface_depth: bool,
        map_surface_depth: bool,
        map_coverage: Option<f32>,
        receiver_coverage: Option<f32>,
    ) -> PyResult<ShadowTest> {
        let [camera] = camera.cameras.as_slice() else {
            return Err(invalid(format!("{} cameras", camera.cameras.len()), "the shadow test takes one camera"));
        };
        let sun = Sun::from_azimuth_elevation(sun.0, sun.1, [sun_intensity; 3]).map_err(py_err)?;
        if !sun.above_horizon() {
            return Err(invalid(
                format!("sun elevation {}°", sun.azimuth_elevation().1),
                "casts no shadow (at or below the horizon)",
            ));
        }
        let mut settings = RelightSettings::preset(Preset::Balanced).shadow;
        settings.resolution = resolution;
        settings.k = k;
        settings.bias = bias;
        settings.slope_bias = slope_bias;
        settings.normal_offset = normal_offset;
        settings.fit = srug::shadow::ShadowFit::parse(fit).map_err(py_err)?;
        settings.filter = srug::shadow::ShadowFilter::parse(filter).map_err(py_err)?;
        settings.tile = tile;
        (settings.surface_depth, settings.map_surface_depth) = (surface_depth, map_surface_depth);
        settings.map_coverage = map_coverage.unwrap_or(settings.map_coverage);
        settings.receiver_coverage = receiver_coverage.unwrap_or(settings.receiver_coverage);
        if let Some(m) = map_depth {
            settings.map_depth = srug::shadow::DepthMode::parse(m).map_err(py_err)?;
        }
        if let Some(m) = receiver_depth {
            settings.receiver_depth = srug::shadow::DepthMode::parse(m).map_err(py_err)?;
        }
        settings.validate().map_err(py_err)?;
        let bounds = scene.info.bounds.ok_or_else(|| invalid("scene", "is empty"))?;
        let device = self.gpu()?;
        let gpu_scene = py.detach(|| scene.gpu(self.id, &device)).map_err(py_err)?;
        let state = py
            .detach(|| -> srug::Result<ShadowState> {
                let mut splatter = Splatter::new(&device)?;
                let pass = ShadowPass::new(&device)?;
                let receivers =
                    splatter.render_frame(&gpu_scene, camera, &SplatSettings { tile, ..settings.receiver_splat() })?;
                let map = pass
                    .shadow_map(&mut splatter, &gpu_scene, &bounds, &sun, &settings, Some(camera))?
                    .ok_or_else(|| srug::Error::invalid("sun", "is below the horizon"))?;
                let (v, _) = pass.visibility(&map, &receivers.gbuffer, camera, &settings, VisibilityKind::Sigmoid)?;
                let mut visibility = vec![0.0f32; camera.width as usize * camera.height as usize];
                device.read_buffer_into(&v, &mut visibility)?;
                Ok(ShadowState {
                    device: device.clone(),
                    scene: gpu_scene,
                    count: scene.info.count,
                    camera: camera.clone(),
                    settings,
                    pass,
                    splatter,
                    map,
                    receivers,
                    visibility: Some(visibility),
                })
            })
            .map_err(py_err)?;
        Ok(ShadowTest { state: Mutex::new(state) })
    }

    fn __repr__(&self) -> String {
        match lock(&self.device).as_ref() {
            Some(d) => format!("srug.Device(\"{}\")", d.info().name),
            None => "srug.Device(closed)".to_string(),
        }
    }
}

/// What a shadow test keeps for its backward pass.
struct ShadowState {
    device: GpuDevice,
    scene: Arc<GpuScene>,
    count: usize,
    camera: Camera,
    settings: ShadowSettings,
    pass: ShadowPass,
    splatter: Splatter,
    map: ShadowMap,
    receivers: SplatFrame,
    /// V, until Python takes it.
    visibility: Option<Vec<f32>>,
}

/// One camera's differentiable shadow test (`Device.shadow`): `visibility`
/// (H, W) float32 and `backward(dl_dv)`.
#[pyclass(frozen, module = "srug._srug")]
struct ShadowTest {
    state: Mutex<ShadowState>,
}

#[pymethods]
impl ShadowTest {
    /// (H, W) of the camera.
    #[getter]
    fn shape(&self) -> (usize, usize) {
        let st = lock(&self.state);
        (st.camera.height as usize, st.camera.width as usize)
    }

    /// V per pixel, (H, W) float32 (a new array on each access).
    #[getter]
    fn visibility<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let mut st = lock(&self.state);
        let (w, h) = (st.camera.width as usize, st.camera.height as usize);
        let v = match st.visibility.take() {
            Some(v) => v,
            None => {
                let v = st.pass.visibility(
                    &st.map,
                    &st.receivers.gbuffer,
                    &st.camera,
                    &st.settings,
                    VisibilityKind::Sigmoid,
                );
                let (buffer, _) = v.map_err(py_err)?;
                st.device.read_buffer(&buffer).map_err(|e| py_err(e.into()))?
            }
        };
        Ok(PyArray1::from_vec(py, v).reshape([h, w])?.into_any())
    }

    /// Gradients of a loss L through V: takes dL/dV (H, W) and returns
    /// dL/d(each Gaussian's mean (G, 3), log-scale (G, 3), rotation (G, 4) as
    /// w, x, y, z, opacity logit (G,)), through both the shadow map's
    /// occluders and the receivers' depths.
    fn backward<'py>(&self, py: Python<'py>, dl_dv: PyReadonlyArrayDyn<'_, f32>) -> PyResult<Bound<'py, PyDict>> {
        let (shape, upstream) = floats(&dl_dv, "dl_dv")?;
        let mut guard = lock(&self.state);
        let st = &mut *guard;
        expect_shape(&shape, &[Some(st.camera.height as usize), Some(st.camera.width as usize)], "dl_dv")?;
        let n = st.count;
        let (mut gm, mut gl, mut gr, mut go) =
            (vec![0.0f32; 3 * n], vec![0.0f32; 3 * n], vec![0.0f32; 4 * n], vec![0.0f32; n]);
        py.detach(|| -> srug::Result<()> {
            let up = st.device.upload("dL/dV", &upstream)?;
            let b = st.pass.backward(
                &st.map,
                &st.receivers.gbuffer,
                &st.camera,
                &st.settings,
                GpuVisibilityLoss::Upstream(&up),
            )?;
            let a = st.splatter.backward(&st.map.frame, &st.scene, &b.map, false)?.read(&st.device)?;
            let c = st.splatter.backward(&st.receivers, &st.scene, &b.receiver, false)?.read(&st.device)?;
            for i in 0..n {
                for j in 0..3 {
                    gm[3 * i + j] = a.means[i][j] + c.means[i][j];
                    gl[3 * i + j] = a.log_scales[i][j] + c.log_scales[i][j];
                }
                for j in 0..4 {
                    gr[4 * i + j] = a.rotations[i][j] + c.rotations[i][j];
                }
                go[i] = a.opacity_logits[i] + c.opacity_logits[i];
            }
            Ok(())
        })
        .map_err(py_err)?;
        let d = PyDict::new(py);
        d.set_item("means", PyArray1::from_vec(py, gm).reshape([n, 3])?)?;
        d.set_item("log_scales", PyArray1::from_vec(py, gl).reshape([n, 3])?)?;
        d.set_item("rotations", PyArray1::from_vec(py, gr).reshape([n, 4])?)?;
        d.set_item("opacity_logits", PyArray1::from_vec(py, go).reshape([n])?)?;
        Ok(d)
    }
}

/// A scene of 3D Gaussians: on the host (from arrays or a file), uploaded
/// to each device on first use, or loaded straight onto a device
/// (`Device.load_scene`), its host arrays then read back only when asked for.
#[pyclass(frozen, module = "srug._srug")]
struct Scene {
    /// The host arrays; `None` for a scene loaded onto a device until needed.
    host: Mutex<Option<Arc<HostScene>>>,
    /// What renders need without the arrays.
    info: SceneInfo,
    /// (device id, upload, device) for each device that holds it.
    uploads: Mutex<Vec<(u64, Arc<GpuScene>, GpuDevice)>>,
    /// Where its Gaussians go on each device it is uploaded to.
    order: SceneOrder,
}

/// A scene's size and attributes, known without its arrays.
struct SceneInfo {
    count: usize,
    sh_degree: u32,
    attributes: srug::scene::AttributeGroups,
    bounds: Option<srug::scene::Bounds>,
}

impl Scene {
    /// A scene from host arrays, arranged as `order` says on each upload.
    fn from_host(host: HostScene, order: SceneOrder) -> Self {
        let info = SceneInfo {
            count: host.len(),
            sh_degree: host.sh_degree,
            attributes: host.attributes(),
            bounds: host.bounds(),
        };
        Self { host: Mutex::new(Some(Arc::new(host))), info, uploads: Mutex::new(Vec::new()), order }
    }

    /// The host arrays, read back from the device the scene was loaded onto if need be.
    fn host(&self) -> srug::Result<Arc<HostScene>> {
        let mut host = lock(&self.host);
        if let Some(h) = host.as_ref() {
            return Ok(h.clone());
        }
        let first = lock(&self.uploads).first().map(|(_, g, d)| (g.clone(), d.clone()));
        let (gpu, device) =
            first.ok_or_else(|| srug::Error::Internal("a scene with neither arrays nor an upload".into()))?;
        let h = Arc::new(gpu.download(&device)?);
        *host = Some(h.clone());
        Ok(h)
    }

    /// The scene on device `id`, uploaded on first use.
    fn gpu(&self, id: u64, device: &GpuDevice) -> srug::Result<Arc<GpuScene>> {
        if let Some((_, g, _)) = lock(&self.uploads).iter().find(|(i, _, _)| *i == id) {
            return Ok(g.clone());
        }
        let host = self.host()?;
        let mut g = GpuScene::upload(device, &host)?;
        g.arrange(device, self.order)?;
        let g = Arc::new(g);
        lock(&self.uploads).push((id, g.clone(), device.clone()));
        Ok(g)
    }
}

#[pymethods]
impl Scene {
    /// Reads a scene file: INRIA PLY, compressed PLY, .splat, .spz, SOG or GLB (detected from the
    /// content). `order`: where its Gaussians go on each device, as `Device.load_scene`'s.
    #[staticmethod]
    #[pyo3(signature = (path, order = "auto"))]
    fn from_file(py: Python<'_>, path: PathBuf, order: &str) -> PyResult<Self> {
        let order = SceneOrder::parse(order).map_err(py_err)?;
        let host = py.detach(|| srug::io::read_scene(&path)).map_err(py_err)?;
        Ok(Self::from_host(host, order))
    }

    /// Writes the scene in the format its extension names (.ply, .spz, .splat,
    /// .sog, .glb; a compressed PLY by `format="compressed-ply"`), atomically.
    #[pyo3(signature = (path, format = None))]
    fn save(&self, py: Python<'_>, path: PathBuf, format: Option<&str>) -> PyResult<()> {
        let format = match format {
            Some(name) => srug::io::SceneFormat::parse(name).map_err(py_err)?,
            None => srug::io::SceneFormat::from_extension(&path).ok_or_else(|| {
                invalid(format!("{}", path.display()), "has no extension naming a scene format (give format=)")
            })?,
        };
        py.detach(|| srug::io::write_scene(&path, &*self.host()?, format)).map_err(py_err)
    }

    /// The scene's arrays as srug stores them: means (N, 3), quats (N, 4) w, x,
    /// y, z (as stored, not normalized), log_scales (N, 3), opacity_logits (N,),
    /// sh (N, K, 3), and where present normals (N, 3) and the relighting
    /// attributes as logits: albedo (N, 3), roughness, metallic, ao, visibility (N,).
    fn arrays<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let h = py.detach(|| self.host()).map_err(py_err)?;
        let n = h.len();
        let k = h.sh.len() / (3 * n.max(1));
        let d = PyDict::new(py);
        let flat = |v: Vec<f32>| PyArray1::from_vec(py, v);
        d.set_item("means", flat(h.means.iter().flatten().copied().collect()).reshape([n, 3])?)?;
        d.set_item("quats", flat(h.rotations.iter().flatten().copied().collect()).reshape([n, 4])?)?;
        d.set_item("log_scales", flat(h.log_scales.iter().flatten().copied().collect()).reshape([n, 3])?)?;
        d.set_item("opacity_logits", flat(h.opacity_logits.clone()).reshape([n])?)?;
        d.set_item("sh", flat(h.sh.clone()).reshape([n, k, 3])?)?;
        let m = &h.materials;
        for (name, triples) in [("normals", &h.normals), ("albedo", &m.albedo)] {
            if let Some(v) = triples {
                d.set_item(name, flat(v.iter().flatten().copied().collect()).reshape([n, 3])?)?;
            }
        }
        for (name, values) in
            [("roughness", &m.roughness), ("metallic", &m.metallic), ("ao", &m.ao), ("visibility", &m.visibility)]
        {
            if let Some(v) = values {
                d.set_item(name, flat(v.clone()).reshape([n])?)?;
            }
        }
        Ok(d)
    }

    /// A scene from arrays, gsplat's names and meanings: `means` (N, 3),
    /// `quats` (N, 4) as w, x, y, z (normalized here), `scales` (N, 3) and
    /// `opacities` (N,) activated (positive; in [0, 1], clamped to
    /// [1e-6, 1 − 1e-6]) unless `activated=False` (then log-scales and
    /// opacity logits, as INRIA PLY stores them), `sh` (N, K, 3) spherical
    /// harmonics with K = 1, 4, 9 or 16. Relighting attributes, optional:
    /// `normals` (N, 3), `albedo` (N, 3), `roughness`, `metallic`, `ao`,
    /// `visibility` (N,), activated (in [0, 1], clamped like opacities) unless
    /// `activated=False` (logits, as srug's PLY stores them). `order`: where the
    /// Gaussians go on each device, as `Device.load_scene`'s ("file" for a scene
    /// made for one frame, as a training step's).
    #[staticmethod]
    #[pyo3(signature = (means, quats, scales, opacities, sh, activated = true, normals = None, albedo = None,
                        roughness = None, metallic = None, ao = None, visibility = None, order = "auto"))]
    #[allow(clippy::too_many_arguments, reason = "the Python keyword arguments of one call")]
    fn from_arrays(
        means: PyReadonlyArrayDyn<'_, f32>,
        quats: PyReadonlyArrayDyn<'_, f32>,
        scales: PyReadonlyArrayDyn<'_, f32>,
        opacities: PyReadonlyArrayDyn<'_, f32>,
        sh: PyReadonlyArrayDyn<'_, f32>,
        activated: bool,
        normals: Option<PyReadonlyArrayDyn<'_, f32>>,
        albedo: Option<PyReadonlyArrayDyn<'_, f32>>,
        roughness: Option<PyReadonlyArrayDyn<'_, f32>>,
        metallic: Option<PyReadonlyArrayDyn<'_, f32>>,
        ao: Option<PyReadonlyArrayDyn<'_, f32>>,
        visibility: Option<PyReadonlyArrayDyn<'_, f32>>,
        order: &str,
    ) -> PyResult<Self> {
        let (ms, m) = floats(&means, "means")?;
        let n = ms.first().copied().unwrap_or(0);
        expect_shape(&ms, &[Some(n), Some(3)], "means")?;
        let (qs, q) = floats(&quats, "quats")?;
        expect_shape(&qs, &[Some(n), Some(4)], "quats")?;
        let (ss, s) = floats(&scales, "scales")?;
        expect_shape(&ss, &[Some(n), Some(3)], "scales")?;
        let (os, o) = floats(&opacities, "opacities")?;
        expect_shape(&os, &[Some(n)], "opacities")?;
        let (hs, sh) = floats(&sh, "sh")?;
        expect_shape(&hs, &[Some(n), None, Some(3)], "sh")?;
        let degree = match hs[1] {
            1 => 0,
            4 => 1,
            9 => 2,
            16 => 3,
            k => return Err(invalid(format!("sh with {k} coefficients"), "must have 1, 4, 9 or 16 (degree 0 to 3)")),
        };
        if let Some(i) = q.chunks_exact(4).position(|r| r.iter().all(|v| *v == 0.0)) {
            return Err(invalid(format!("quats row {i}"), "is zero (not a rotation)"));
        }
        let log_scales = if activated {
            if let Some(i) = s.iter().position(|v| *v <= 0.0) {
                return Err(invalid(format!("scales element {i}"), format!("is {} (activated scales are > 0)", s[i])));
            }
            s.iter().map(|v| v.ln()).collect::<Vec<f32>>()
        } else {
            s
        };
        let opacity_logits = logits(o, activated, "opacities")?;
        // A relighting attribute of `k` floats per Gaussian, as logits.
        let attribute = |a: Option<PyReadonlyArrayDyn<'_, f32>>, k: usize, what: &str| -> PyResult<Option<Vec<f32>>> {
            let Some(a) = a else { return Ok(None) };
            let (shape, v) = floats(&a, what)?;
            let want: Vec<Option<usize>> = if k == 1 { vec![Some(n)] } else { vec![Some(n), Some(k)] };
            expect_shape(&shape, &want, what)?;
            logits(v, activated, what).map(Some)
        };
        let triples = |v: Vec<f32>| v.chunks_exact(3).map(|r| [r[0], r[1], r[2]]).collect::<Vec<_>>();
        let normals = match normals {
            Some(a) => {
                let (shape, v) = floats(&a, "normals")?;
                expect_shape(&shape, &[Some(n), Some(3)], "normals")?;
                Some(triples(v))
            }
            None => None,
        };
        let materials = srug::scene::Materials {
            albedo: attribute(albedo, 3, "albedo")?.map(triples),
            roughness: attribute(roughness, 1, "roughness")?,
            metallic: attribute(metallic, 1, "metallic")?,
            ao: attribute(ao, 1, "ao")?,
            visibility: attribute(visibility, 1, "visibility")?,
        };
        let host = HostScene {
            means: m.chunks_exact(3).map(|r| [r[0], r[1], r[2]]).collect(),
            log_scales: log_scales.chunks_exact(3).map(|r| [r[0], r[1], r[2]]).collect(),
            rotations: q.chunks_exact(4).map(|r| [r[0], r[1], r[2], r[3]]).collect(),
            opacity_logits,
            sh_degree: degree,
            sh,
            normals,
            materials,
            ..HostScene::default()
        };
        host.validate("arrays").map_err(|e| py_err(e.into()))?;
        Ok(Self::from_host(host, SceneOrder::parse(order).map_err(py_err)?))
    }

    /// The number of Gaussians.
    #[getter]
    fn count(&self) -> usize {
        self.info.count
    }

    fn __len__(&self) -> usize {
        self.info.count
    }

    /// The spherical-harmonic degree stored.
    #[getter]
    fn sh_degree(&self) -> u32 {
        self.info.sh_degree
    }

    /// Whether the scene can be relit (it has an albedo attribute).
    #[getter]
    fn relightable(&self) -> bool {
        self.info.attributes.shadeable()
    }

    /// ((min x, y, z), (max x, y, z)) of the Gaussian centres; None when empty.
    #[getter]
    fn bounds(&self) -> Option<(Point, Point)> {
        self.info.bounds.map(|b| ((b.min[0], b.min[1], b.min[2]), (b.max[0], b.max[1], b.max[2])))
    }

    fn __repr__(&self) -> String {
        format!("srug.Scene({} Gaussians, SH degree {})", self.info.count, self.info.sh_degree)
    }
}

/// A list of cameras (pose, intrinsics, lens, image size).
#[pyclass(frozen, module = "srug._srug")]
struct Cameras {
    cameras: Vec<Camera>,
}

#[pymethods]
impl Cameras {
    /// Cameras as gsplat takes them: `viewmats` (N, 4, 4) world-to-camera with
    /// OpenCV axes (x right, y down, z forward), `ks` (N, 3, 3) pinhole
    /// intrinsics in pixels (pixel centres at +0.5), one `width` × `height`.
    #[new]
    #[pyo3(signature = (viewmats, ks, width, height, near = DEFAULT_NEAR, far = DEFAULT_FAR, names = None))]
    #[allow(clippy::too_many_arguments, reason = "the Python keyword arguments of one call")]
    fn new(
        viewmats: PyReadonlyArrayDyn<'_, f32>,
        ks: PyReadonlyArrayDyn<'_, f32>,
        width: u32,
        height: u32,
        near: f32,
        far: f32,
        names: Option<Vec<String>>,
    ) -> PyResult<Self> {
        let (vs, v) = floats(&viewmats, "viewmats")?;
        let n = vs.first().copied().unwrap_or(0);
        expect_shape(&vs, &[Some(n), Some(4), Some(4)], "viewmats")?;
        let (kshape, k) = floats(&ks, "Ks")?;
        expect_shape(&kshape, &[Some(n), Some(3), Some(3)], "Ks")?;
        if n == 0 {
            return Err(invalid("viewmats", "holds no camera"));
        }
        if let Some(names) = &names {
            if names.len() != n {
                return Err(invalid(format!("names ({} of them)", names.len()), format!("must name all {n} cameras")));
            }
        }
        let mut cameras = Vec::with_capacity(n);
        for i in 0..n {
            let m = &v[16 * i..16 * i + 16];
            let kk = &k[9 * i..9 * i + 9];
            if m[12..16] != [0.0, 0.0, 0.0, 1.0] {
                return Err(invalid(format!("viewmats[{i}]"), "has a last row other than (0, 0, 0, 1)"));
            }
            if kk[1] != 0.0 || kk[3] != 0.0 || kk[6..9] != [0.0, 0.0, 1.0] {
                return Err(invalid(
                    format!("Ks[{i}]"),
                    "is not [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] (skew is not supported)",
                ));
            }
            // Row-major world-to-camera [R | t]: the camera-to-world rotation is Rᵀ, the centre −Rᵀt.
            let r = Mat3::from_cols_array(&[m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10]]);
            let t = Vec3::new(m[3], m[7], m[11]);
            let camera = Camera {
                name: names.as_ref().map_or_else(|| format!("camera_{i}"), |n| n[i].clone()),
                width,
                height,
                rotation: r,
                position: srug::camera::centre_of(r, t),
                projection: Projection::Pinhole { fx: kk[0], fy: kk[4], cx: kk[2], cy: kk[5] },
                near,
                far,
                lens: srug::camera::lens::Lens::Pinhole,
            };
            camera.validate().map_err(|e| invalid(format!("camera {i}"), e.to_string()))?;
            cameras.push(camera);
        }
        Ok(Self { cameras })
    }

    /// Reads a cameras file: INRIA cameras.json, a COLMAP sparse model (its
    /// folder or its cameras/images file, text or binary) or a
    /// nerfstudio/instant-ngp transforms.json (detected), lenses included.
    #[staticmethod]
    fn from_file(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let cameras = py.detach(|| srug::io::read_cameras(&path)).map_err(py_err)?;
        Ok(Self { cameras })
    }

    /// The same cameras with images `width` × `height` (intrinsics scaled).
    fn resized(&self, width: u32, height: u32) -> PyResult<Self> {
        if width == 0 || height == 0 {
            return Err(invalid(format!("size {width}x{height}"), "is empty"));
        }
        Ok(Self { cameras: self.cameras.iter().map(|c| c.resized(width, height)).collect() })
    }

    /// Each camera as a 360° × 180° equirectangular panorama `width` × `width / 2`
    /// from its position (depth: the distance from the camera).
    fn panoramas(&self, width: u32) -> PyResult<Self> {
        let mut out = Vec::with_capacity(self.cameras.len());
        for c in &self.cameras {
            let p = Camera::panorama(c.position, c.rotation, width).map_err(py_err)?;
            out.push(Camera { name: c.name.clone(), near: c.near, far: c.far, ..p });
        }
        Ok(Self { cameras: out })
    }

    /// The cameras at `indices`, in that order.
    fn select(&self, indices: Vec<usize>) -> PyResult<Self> {
        let n = self.cameras.len();
        let mut out = Vec::with_capacity(indices.len());
        for i in indices {
            out.push(
                self.cameras
                    .get(i)
                    .cloned()
                    .ok_or_else(|| invalid(format!("camera index {i}"), format!("there are {n} cameras")))?,
            );
        }
        Ok(Self { cameras: out })
    }

    fn __len__(&self) -> usize {
        self.cameras.len()
    }

    /// The cameras' names (image names where the file has them).
    #[getter]
    fn names(&self) -> Vec<String> {
        self.cameras.iter().map(|c| c.name.clone()).collect()
    }

    /// Each camera's (width, height).
    #[getter]
    fn sizes(&self) -> Vec<(u32, u32)> {
        self.cameras.iter().map(|c| (c.width, c.height)).collect()
    }

    /// Each camera's lens, as `repr` text ("Pinhole", "RadialTangential { … }", "Equirectangular", …).
    #[getter]
    fn lenses(&self) -> Vec<String> {
        self.cameras.iter().map(|c| format!("{:?}", c.lens)).collect()
    }

    /// (N, 4, 4) float32 world-to-camera matrices, OpenCV axes.
    #[getter]
    fn viewmats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let mut v = Vec::with_capacity(16 * self.cameras.len());
        for c in &self.cameras {
            let r = c.rotation.transpose();
            let t = -(r * c.position);
            for row in 0..3 {
                v.extend([r.x_axis[row], r.y_axis[row], r.z_axis[row], t[row]]);
            }
            v.extend([0.0, 0.0, 0.0, 1.0]);
        }
        Ok(PyArray1::from_vec(py, v).reshape([self.cameras.len(), 4, 4])?.into_any())
    }

    /// (N, 3, 3) float32 intrinsics (fx, fy, cx, cy; lenses are not in it).
    #[getter]
    fn ks<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let mut v = Vec::with_capacity(9 * self.cameras.len());
        for c in &self.cameras {
            let (fx, fy, cx, cy) = match c.projection {
                Projection::Pinhole { fx, fy, cx, cy } | Projection::Orthographic { sx: fx, sy: fy, cx, cy } => {
                    (fx, fy, cx, cy)
                }
            };
            v.extend([fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0]);
        }
        Ok(PyArray1::from_vec(py, v).reshape([self.cameras.len(), 3, 3])?.into_any())
    }

    fn __repr__(&self) -> String {
        format!("srug.Cameras({} cameras)", self.cameras.len())
    }
}

/// The built-in demo city (`srug demo`): a relightable scene of `gaussians`
/// Gaussians and its street cameras (704x192), made deterministically from `seed`.
#[pyfunction]
#[pyo3(signature = (gaussians = 200_000, seed = 7, sh_degree = 1))]
fn demo_city(py: Python<'_>, gaussians: usize, seed: u64, sh_degree: u32) -> PyResult<(Scene, Cameras)> {
    let options = srug::scene::demo::DemoOptions { gaussians, seed, sh_degree };
    let city = py.detach(|| srug::scene::demo::demo_city(&options)).map_err(py_err)?;
    Ok((Scene::from_host(city.scene, SceneOrder::Auto), Cameras { cameras: city.cameras }))
}

/// The sun's (azimuth, elevation) in degrees at `time` (ISO 8601 with a zone,
/// e.g. "2024-06-21T14:30+02:00") seen from `latitude`, `longitude` (degrees,
/// east positive), by NOAA's formulas (as `srug relight --sun-time`).
#[pyfunction]
fn sun_position(time: &str, latitude: f64, longitude: f64) -> PyResult<(f64, f64)> {
    let t = srug::shadow::UtcTime::parse(time).map_err(py_err)?;
    let p = srug::shadow::solar_position(&t, latitude, longitude).map_err(py_err)?;
    Ok((p.azimuth, p.elevation))
}

/// The srug version.
#[pyfunction]
fn version() -> &'static str {
    env!("CARGO_PKG_VERSION")
}

#[pymodule]
fn _srug(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("Error", m.py().get_type::<Error>())?;
    m.add_class::<Device>()?;
    m.add_class::<Scene>()?;
    m.add_class::<Cameras>()?;
    m.add_class::<ShadowTest>()?;
    m.add_function(wrap_pyfunction!(version, m)?)?;
    m.add_function(wrap_pyfunction!(demo_city, m)?)?;
    m.add_function(wrap_pyfunction!(sun_position, m)?)?;
    Ok(())
}
