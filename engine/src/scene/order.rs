//! The order of a scene's Gaussians: along a Morton curve through their
//! centres on the host ([`morton_order`]) and on the device
//! ([`GpuScene::arrange`]).
//!
//! Why: a trained scene's file lists its Gaussians in no spatial order
//! (training appends the ones it splits and clones), so the lanes of a SIMD
//! row (a lavapipe row of eight, a GPU's subgroup) mix culled and kept
//! Gaussians and splats of every size, each row waiting for its slowest lane
//! in the preprocess and the keys kernel, and a tile's splat records lie all
//! over memory for the blend. Rendering is the same in any order (splats whose
//! depth keys tie blend in scene order).
//!
//! Invariants of an arranged [`GpuScene`] ([`GpuScene::row_order`] is `Some`):
//! - every buffer of the scene holds the Gaussians in device order: device row
//!   `d` is file row [`RowOrder::to_file`]`[d]`, for every attribute alike;
//! - every Gaussian index or per-Gaussian array leaves the engine in file
//!   order: the splat forward maps the `top_gaussian` ids, the splat backward
//!   its gradients (and so the shadow backward's), [`GpuScene::download`] and
//!   [`GpuScene::write_geometry`] their arrays, so callers never see the
//!   device order unless they read the scene's buffers themselves.

use std::sync::Arc;

use bytemuck::Zeroable;

use super::activate::GpuScene;
use super::layout::ReorderPush;
use super::Bounds;
use crate::error::{Error, Result};
use crate::gpu::{kernels, Buffer, Device, Grid, Kernel, KernelDecl, Recording, SpecValue};

/// Where a scene's Gaussians go on the device.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SceneOrder {
    /// As the file lists them.
    File,
    /// Along a Morton curve through their centres.
    Morton,
    /// Along the Morton curve when the file lists them in no spatial order
    /// ([`in_spatial_order`] false), else as the file does.
    #[default]
    Auto,
}

impl SceneOrder {
    /// Parses `file`, `morton` or `auto`.
    pub fn parse(text: &str) -> Result<Self> {
        match text {
            "file" => Ok(Self::File),
            "morton" => Ok(Self::Morton),
            "auto" => Ok(Self::Auto),
            other => Err(Error::invalid(format!("scene order \"{other}\""), "is not file, morton or auto")),
        }
    }

    /// The name [`SceneOrder::parse`] reads.
    pub fn name(self) -> &'static str {
        match self {
            Self::File => "file",
            Self::Morton => "morton",
            Self::Auto => "auto",
        }
    }
}

/// Indices of `means` sorted by the Morton code of the centres quantized to
/// 1024 cells an axis over `b` (centres outside it in the edge cells,
/// non-finite ones last; ties keep their order).
pub fn morton_order(means: &[[f32; 3]], b: &Bounds) -> Vec<usize> {
    let cell = |v: f32, a: usize| -> u64 {
        let (lo, hi) = (b.min[a], b.max[a]);
        if hi > lo {
            ((v - lo) / (hi - lo) * 1023.0).clamp(0.0, 1023.0) as u64
        } else {
            0
        }
    };
    // The low 10 bits of x, two zero bits after each.
    let spread = |mut x: u64| {
        x &= 0x3ff;
        x = (x | x << 16) & 0x0300_00ff;
        x = (x | x << 8) & 0x0300_f00f;
        x = (x | x << 4) & 0x030c_30c3;
        (x | x << 2) & 0x0924_9249
    };
    let key = |p: &[f32; 3]| {
        if p.iter().all(|v| v.is_finite()) {
            spread(cell(p[0], 0)) | spread(cell(p[1], 1)) << 1 | spread(cell(p[2], 2)) << 2
        } else {
            1 << 30
        }
    };
    // The 30-bit code (2³⁰ for non-finite centres) above a 32-bit index: one unstable sort of u64s,
    // ties in index order. Past 2³² Gaussians, pairs.
    if u32::try_from(means.len()).is_ok() {
        let mut keyed: Vec<u64> = means.iter().enumerate().map(|(i, p)| key(p) << 32 | i as u64).collect();
        keyed.sort_unstable();
        keyed.into_iter().map(|k| (k & 0xffff_ffff) as usize).collect()
    } else {
        let mut keyed: Vec<(u64, usize)> = means.iter().enumerate().map(|(i, p)| (key(p), i)).collect();
        keyed.sort_unstable();
        keyed.into_iter().map(|(_, i)| i).collect()
    }
}

/// Bounds of `means` between the `tail` and 1 − `tail` quantiles on each axis
/// (`tail` in [0, 0.5)); `None` when empty.
pub fn core_bounds(means: &[[f32; 3]], tail: f32) -> Option<Bounds> {
    if means.is_empty() || !(0.0..0.5).contains(&tail) {
        return None;
    }
    let n = means.len();
    let (lo_i, hi_i) = (((n - 1) as f32 * tail) as usize, ((n - 1) as f32 * (1.0 - tail)).ceil() as usize);
    let mut b = Bounds { min: [0.0; 3], max: [0.0; 3] };
    let mut axis: Vec<f32> = Vec::with_capacity(n);
    for a in 0..3 {
        axis.clear();
        axis.extend(means.iter().map(|p| p[a]));
        b.min[a] = *axis.select_nth_unstable_by(lo_i, f32::total_cmp).1;
        b.max[a] = *axis.select_nth_unstable_by(hi_i.min(n - 1), f32::total_cmp).1;
    }
    Some(b)
}

/// The median distance between consecutive centres taken in `order` (every
/// index once; `None`: as listed), over pairs of finite centres; `None` with
/// fewer than two such pairs.
pub fn median_step(means: &[[f32; 3]], order: Option<&[usize]>) -> Option<f32> {
    let step = |a: usize, b: usize| -> Option<f32> {
        let d = glam::Vec3::from(*means.get(a)?).distance(glam::Vec3::from(*means.get(b)?));
        d.is_finite().then_some(d)
    };
    let mut steps: Vec<f32> = match order {
        Some(o) => o.windows(2).filter_map(|w| step(w[0], w[1])).collect(),
        None => (1..means.len()).filter_map(|i| step(i - 1, i)).collect(),
    };
    median(&mut steps)
}

fn median(values: &mut [f32]) -> Option<f32> {
    if values.len() < 2 {
        return None;
    }
    let mid = values.len() / 2;
    Some(*values.select_nth_unstable_by(mid, f32::total_cmp).1)
}

/// Consecutive pairs [`in_spatial_order`] samples.
const ORDER_SAMPLES: usize = 4096;

/// Scenes of fewer Gaussians count as in a spatial order (nothing to gain).
const ORDER_MIN_GAUSSIANS: usize = 64;

/// The rows [`in_spatial_order`] reads for `n` Gaussians (at least
/// [`ORDER_MIN_GAUSSIANS`]): for each sample a row, the next one, and a partner
/// drawn at random (SplitMix64 from a fixed seed: the same rows on every run).
fn order_sample_rows(n: usize) -> Vec<u32> {
    let samples = ORDER_SAMPLES.min(n - 1);
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut random = || {
        state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    };
    (0..samples)
        .flat_map(|s| {
            let i = s * (n - 1) / samples;
            [i, i + 1, (random() % n as u64) as usize].map(|r| r as u32)
        })
        .collect()
}

/// [`in_spatial_order`]'s test on the centres of [`order_sample_rows`], in that order.
fn spatial_order_of_samples(points: &[[f32; 3]]) -> bool {
    let dist = |a: [f32; 3], b: [f32; 3]| {
        let d = glam::Vec3::from(a).distance(glam::Vec3::from(b));
        d.is_finite().then_some(d)
    };
    let next = points.chunks_exact(3).filter_map(|t| dist(t[0], t[1]));
    let far = points.chunks_exact(3).filter_map(|t| dist(t[0], t[2]));
    let (mut next, mut far): (Vec<f32>, Vec<f32>) = (next.collect(), far.collect());
    match (median(&mut next), median(&mut far)) {
        (Some(step), Some(spread)) => step < 0.25 * spread,
        _ => true,
    }
}

/// Whether the centres, as listed, lie in a spatial order: on a sample of
/// 4096 places, the median distance between consecutive centres
/// is under a quarter of the median distance between centres paired at
/// random (a random order's ratio is about one). Scenes of fewer than 64
/// Gaussians count as ordered (nothing to gain). Deterministic.
pub fn in_spatial_order(means: &[[f32; 3]]) -> bool {
    if means.len() < ORDER_MIN_GAUSSIANS {
        return true;
    }
    let points: Vec<[f32; 3]> = order_sample_rows(means.len()).iter().map(|&r| means[r as usize]).collect();
    spatial_order_of_samples(&points)
}

/// Bytes of scratch [`GpuScene::arrange`] may use beyond [`ARRANGE_MIN_WORDS`] a Gaussian.
const ARRANGE_SCRATCH_BYTES: usize = 64 << 20;

/// Words a Gaussian [`GpuScene::arrange`] moves at a time at least (its scratch
/// holds this many a Gaussian at any scene size, where its rows are as long):
/// 48 bytes, under the 64-byte splat record that every frame of the scene
/// allocates for each Gaussian, so the scratch, pooled when the first frame
/// starts, is freed before it could raise that frame's peak. Each block is a
/// scatter of every row to a random place: fewer, wider blocks move a large
/// scene's rows faster (docs/bench/splat.md, "Arranged on the device").
const ARRANGE_MIN_WORDS: u32 = 12;

/// Words of a row [`GpuScene::arrange`] moves at a time for `n` Gaussians:
/// within [`ARRANGE_SCRATCH_BYTES`] of scratch, at least [`ARRANGE_MIN_WORDS`],
/// at most the longest row (an SH-3 row's 48).
fn arrange_words(n: usize, longest_row: u32) -> u32 {
    let fit = ARRANGE_SCRATCH_BYTES / (4 * n.max(1));
    (fit.min(longest_row as usize) as u32).max(ARRANGE_MIN_WORDS).min(longest_row).max(1)
}

/// The device order of an arranged [`GpuScene`].
pub struct RowOrder {
    to_file: Vec<u32>,
    device_to_file: Buffer,
    file_to_device: Buffer,
}

impl RowOrder {
    fn new(device: &Device, to_file: Vec<u32>) -> Result<Self> {
        let mut to_device = vec![0u32; to_file.len()];
        for (d, &f) in to_file.iter().enumerate() {
            to_device[f as usize] = d as u32;
        }
        Ok(Self {
            device_to_file: device.upload("scene rows to file rows", &to_file)?,
            file_to_device: device.upload("file rows to scene rows", &to_device)?,
            to_file,
        })
    }

    /// Device row → file row.
    pub fn to_file(&self) -> &[u32] {
        &self.to_file
    }

    /// File row → device row, as indices: [`super::Scene::permuted`] by these
    /// lists device-ordered arrays in file order again.
    pub fn to_device_indices(&self) -> Vec<usize> {
        let mut order = vec![0usize; self.to_file.len()];
        for (d, &f) in self.to_file.iter().enumerate() {
            order[f as usize] = d;
        }
        order
    }

    /// [`RowOrder::to_file`] on the device, `uint[N]`.
    pub fn device_to_file(&self) -> &Buffer {
        &self.device_to_file
    }

    /// File row → device row on the device, `uint[N]`.
    pub fn file_to_device(&self) -> &Buffer {
        &self.file_to_device
    }

    /// `rows` (`per` values a Gaussian, listed in file order) in device order.
    pub fn rows_to_device<T: Copy>(&self, rows: &[T], per: usize) -> Vec<T> {
        gather_rows(&self.to_file, rows, per)
    }

    /// `rows` (`per` values a Gaussian, in device order) in file order.
    pub fn rows_to_file<T: Copy + Default>(&self, rows: &[T], per: usize) -> Vec<T> {
        scatter_rows(&self.to_file, rows, per)
    }
}

/// Row `d` of the result is row `index[d]` of `rows` (`per` values a row).
fn gather_rows<T: Copy>(index: &[u32], rows: &[T], per: usize) -> Vec<T> {
    index.iter().flat_map(|&f| &rows[f as usize * per..(f as usize + 1) * per]).copied().collect()
}

/// Row `index[d]` of the result is row `d` of `rows`: [`gather_rows`] undone.
fn scatter_rows<T: Copy + Default>(index: &[u32], rows: &[T], per: usize) -> Vec<T> {
    let mut out = vec![T::default(); rows.len()];
    for (d, &f) in index.iter().enumerate() {
        out[f as usize * per..(f as usize + 1) * per].copy_from_slice(&rows[d * per..(d + 1) * per]);
    }
    out
}

/// Which rows [`ReorderKernels::record_rows`] moves where.
#[derive(Clone, Copy)]
pub(crate) enum RowMap<'a> {
    /// Row i to row i.
    Same,
    /// Row `index[i]` to row i.
    Gather(&'a Buffer),
    /// Row i to row `index[i]`: reads in order, writes scattered (cheaper
    /// where reads that miss the cache stall and writes do not).
    Scatter(&'a Buffer),
}

/// The kernels of `scene_reorder.comp`: rows moved by an index, and ids mapped.
pub(crate) struct ReorderKernels {
    gather: Arc<Kernel>,
    ids: Arc<Kernel>,
    scatter: Arc<Kernel>,
}

impl ReorderKernels {
    pub(crate) fn new(device: &Device) -> Result<Self> {
        let kernel = |mode: u32| {
            device.kernel(&kernels::SCENE_REORDER, &KernelDecl::push::<ReorderPush>(&[(0, SpecValue::U32(mode))]))
        };
        Ok(Self { gather: kernel(0)?, ids: kernel(1)?, scatter: kernel(2)? })
    }

    /// Records, for `count` rows, words `src_first..+width` of `src` rows
    /// `src_stride` words long into words `dst_first..+width` of `dst` rows
    /// `dst_stride` long, the rows matched by `map`.
    pub(crate) fn record_rows<'a>(
        &'a self,
        rec: &mut Recording<'a>,
        src: (&'a Buffer, u32, u32),
        dst: (&'a Buffer, u32, u32),
        map: RowMap<'a>,
        count: u64,
        width: u32,
    ) -> Result<()> {
        let (kernel, index) = match map {
            RowMap::Same => (&self.gather, None),
            RowMap::Gather(index) => (&self.gather, Some(index)),
            RowMap::Scatter(index) => (&self.scatter, Some(index)),
        };
        let push = ReorderPush {
            src: rec.addr(src.0)?,
            dst: rec.addr(dst.0)?,
            index: rec.addr_or_null(index)?,
            count: rows_u32(count)?,
            width,
            src_stride: src.1,
            src_first: src.2,
            dst_stride: dst.1,
            dst_first: dst.2,
        };
        Ok(rec.dispatch(kernel, Grid::Items(count), &[], &push)?)
    }

    /// Records `ids[i] = order.to_file[ids[i]]` in place for `count` ids
    /// (ids past the order, "none", kept).
    pub(crate) fn record_ids<'a>(
        &'a self,
        rec: &mut Recording<'a>,
        ids: &'a Buffer,
        count: u64,
        order: &'a RowOrder,
    ) -> Result<()> {
        self.record_ids_through(rec, ids, count, &order.device_to_file, order.to_file.len() as u64)
    }

    /// Records `ids[i] = table[ids[i]]` in place for `count` ids, where
    /// `ids[i] < width` (`table` holds `width` u32; others, "none", kept).
    pub(crate) fn record_ids_through<'a>(
        &'a self,
        rec: &mut Recording<'a>,
        ids: &'a Buffer,
        count: u64,
        table: &'a Buffer,
        width: u64,
    ) -> Result<()> {
        let addr = rec.addr(ids)?;
        let push = ReorderPush {
            src: addr,
            dst: addr,
            index: rec.addr(table)?,
            count: rows_u32(count)?,
            width: rows_u32(width)?,
            ..ReorderPush::zeroed()
        };
        Ok(rec.dispatch(&self.ids, Grid::Items(count), &[], &push)?)
    }
}

fn rows_u32(count: u64) -> Result<u32> {
    u32::try_from(count).map_err(|_| Error::invalid(format!("{count} rows"), "exceed the 2³² − 1 a reorder indexes"))
}

impl GpuScene {
    /// Puts the Gaussians on the device in `order` (module doc): reads the
    /// centres back, sorts them on the host, and moves every attribute's rows
    /// on the device a block of words at a time (scratch of at least 16 bytes a
    /// Gaussian, 64 MiB where that holds more).
    /// Returns whether the rows moved; a scene already arranged stays as it is.
    pub fn arrange(&mut self, device: &Device, order: SceneOrder) -> Result<bool> {
        self.arrange_in_blocks(device, order, None)
    }

    /// [`in_spatial_order`] of the scene's centres as they lie on the device,
    /// reading back only the sampled rows (gathered on the device).
    pub fn in_spatial_order(&self, device: &Device) -> Result<bool> {
        let n = self.count;
        if n < ORDER_MIN_GAUSSIANS {
            return Ok(true);
        }
        rows_u32(n as u64)?;
        let rows = order_sample_rows(n);
        let index = device.upload("order sample rows", &rows)?;
        let count = rows.len() as u64;
        let points = device.create_filled::<[f32; 3]>("order sample centres", rows.len(), 0x7fc0_0000)?;
        let kernels = ReorderKernels::new(device)?;
        device.run(|rec| {
            kernels.record_rows(rec, (&self.means, 3, 0), (&points, 3, 0), RowMap::Gather(&index), count, 3)
        })?;
        Ok(spatial_order_of_samples(&device.read_buffer::<[f32; 3]>(&points)?))
    }

    /// [`GpuScene::arrange`] moving `words` of a row at a time (at least one;
    /// `None`: as many as its scratch budget allows). For tests of the block path.
    #[doc(hidden)]
    pub fn arrange_in_blocks(&mut self, device: &Device, order: SceneOrder, words: Option<u32>) -> Result<bool> {
        let n = self.count;
        if order == SceneOrder::File || n < 2 || self.row_order().is_some() {
            return Ok(false);
        }
        rows_u32(n as u64)?;
        let start = std::time::Instant::now();
        if order == SceneOrder::Auto && self.in_spatial_order(device)? {
            return Ok(false);
        }
        let means: Vec<[f32; 3]> = device.read_buffer(&self.means)?;
        let Some(bounds) = core_bounds(&means[..n], 0.001) else { return Ok(false) };
        let to_file: Vec<u32> = morton_order(&means[..n], &bounds).into_iter().map(|i| i as u32).collect();
        drop(means);
        let sorted = start.elapsed();
        let rows = RowOrder::new(device, to_file)?;
        let kernels = ReorderKernels::new(device)?;
        let buffers = self.row_buffers();
        let longest = buffers.iter().map(|(_, row)| *row).max().unwrap_or(1);
        let words = words.map_or_else(|| arrange_words(n, longest), |w| w.clamp(1, longest));
        let scratch = device.create_filled::<u32>("scene reorder scratch", n * words as usize, 0x7fc0_0000)?;
        let count = n as u64;
        let moved = std::time::Instant::now();
        let timings = device.run(|rec| -> Result<()> {
            for &(buffer, row) in &buffers {
                rec.begin_stage(buffer.name());
                for first in (0..row).step_by(words as usize) {
                    let width = words.min(row - first);
                    let map = RowMap::Scatter(&rows.file_to_device);
                    kernels.record_rows(rec, (buffer, row, first), (&scratch, width, 0), map, count, width)?;
                    if width == row {
                        // Whole rows: back in one copy.
                        rec.copy(&scratch, 0, buffer, 0, 4 * u64::from(row) * count)?;
                    } else {
                        let back = RowMap::Same;
                        kernels.record_rows(rec, (&scratch, width, 0), (buffer, row, first), back, count, width)?;
                    }
                }
            }
            Ok(())
        })?;
        self.set_row_order(rows);
        log::debug!(
            "arranged {n} Gaussians along a Morton curve in {:.3} s ({:.3} s reading and sorting the centres, \
             {:.3} s moving the rows of which {:.3} s GPU)",
            start.elapsed().as_secs_f64(),
            sorted.as_secs_f64(),
            moved.elapsed().as_secs_f64(),
            timings.total_seconds()
        );
        log::debug!("{timings}");
        Ok(true)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "a failed unwrap is a failed test")]
    use super::*;

    #[test]
    fn arrange_moves_whole_rows_of_small_scenes_and_twelve_words_of_large_ones() {
        assert_eq!(arrange_words(100_000, 48), 48, "an SH-3 row whole within 64 MiB");
        assert_eq!(arrange_words(1_000_000, 48), 16, "64 MiB over 1M Gaussians: 16 words");
        assert_eq!(arrange_words(10_000_000, 48), 12, "at least 12 words a Gaussian");
        assert_eq!(arrange_words(10_000_000, 4), 4, "never more than the longest row");
        assert_eq!(arrange_words(0, 0), 1);
    }

    #[test]
    fn scene_orders_parse_by_name() {
        for o in [SceneOrder::File, SceneOrder::Morton, SceneOrder::Auto] {
            assert_eq!(SceneOrder::parse(o.name()).ok(), Some(o));
        }
        let e = SceneOrder::parse("hilbert").unwrap_err().to_string();
        assert!(e.contains("hilbert") && e.contains("file, morton or auto"), "{e}");
    }

    #[test]
    fn a_grid_listed_in_order_is_spatial_and_shuffled_is_not() {
        let grid: Vec<[f32; 3]> =
            (0..32 * 32 * 8).map(|c| [(c % 32) as f32, ((c / 32) % 32) as f32, (c / 1024) as f32]).collect();
        assert!(in_spatial_order(&grid), "row by row");
        let shuffled: Vec<[f32; 3]> = (0..grid.len()).map(|i| grid[(i * 2654435761) % grid.len()]).collect();
        assert!(!in_spatial_order(&shuffled), "scrambled");
        let b = core_bounds(&shuffled, 0.0).unwrap();
        let morton: Vec<[f32; 3]> = morton_order(&shuffled, &b).into_iter().map(|i| shuffled[i]).collect();
        assert!(in_spatial_order(&morton), "along the curve");
        assert!(in_spatial_order(&grid[..63]), "too few to judge");
    }

    #[test]
    fn row_maps_round_trip() {
        let to_file = [2u32, 0, 3, 1];
        let rows = |o: &[u32]| -> Vec<f32> { o.iter().flat_map(|&f| [f as f32, 10.0 + f as f32]).collect() };
        let file: Vec<f32> = rows(&[0, 1, 2, 3]);
        let device = gather_rows(&to_file, &file, 2);
        assert_eq!(device, rows(&to_file));
        assert_eq!(scatter_rows(&to_file, &device, 2), file);
    }
}
