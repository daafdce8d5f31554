//! Exclusive prefix sum of `u32` on the GPU (reduce-then-scan), in one of
//! two shapes chosen per device ([`default_scan_tiles`]):
//!
//! - **Runs** (CPU devices): every invocation owns a run of consecutive
//!   values: `scan_reduce.comp` sums them, the sums are scanned the same way
//!   (recursively, until one invocation holds everything), and
//!   `scan_apply.comp` rewrites each run as its exclusive prefix from the
//!   run's scanned sum. Invocations work alone in registers: no shared memory
//!   (on CPU implementations such as lavapipe a shared-memory access indexed
//!   by lane is a loop over the lanes; the earlier shared-memory
//!   Hillis–Steele scan was several times slower there). Runs are as long as
//!   [`RUN_INVOCATIONS`] invocations need to cover the values (at least
//!   [`MIN_RUN`]), and one invocation takes up to [`MAX_SINGLE_RUN`] values
//!   alone, so every scan is at most three dispatches: on lavapipe each
//!   dispatch costs more than the additions of thousands of values.
//! - **Tiles** (GPUs): every workgroup owns [`SCAN_TILE`] consecutive values,
//!   read and written by neighbouring invocations at neighbouring addresses
//!   and scanned across invocations in shared memory
//!   (`scan_tiles_reduce.comp`, `scan_tiles_apply.comp`), so a scan of up
//!   to 4 million values takes three dispatches (runs of 32 values took up
//!   to nine: on a GPU each dispatch and its barrier, not the arithmetic, was
//!   most of a scan's time). Long runs would not do there: 256 invocations,
//!   each reading its own stretch, leave a GPU nearly idle.
//!
//! Neither uses subgroup operations or has a workgroup wait on another, so
//! no forward-progress guarantee is needed. Sums wrap modulo 2³² like `u32`.

use bytemuck::{Pod, Zeroable};
use std::sync::Arc;

use crate::error::Result;
use crate::gpu::ash::vk;
use crate::gpu::{kernels, Buffer, Device, DeviceAddress, Grid, Kernel, KernelDecl, MemoryKind, Recording};

/// Fewest values an invocation of a run scan owns.
pub const MIN_RUN: u64 = 32;
/// Invocations a level of a run scan spreads its values over: enough for a
/// CPU device's threads and lanes, few enough that their sums fit one run.
pub const RUN_INVOCATIONS: u64 = 256;
/// Most values one invocation scans alone (a level's last).
pub const MAX_SINGLE_RUN: u64 = 4096;

/// Values each invocation owns in a run scan of `count` values: all of them
/// up to [`MAX_SINGLE_RUN`], else a share of [`RUN_INVOCATIONS`] (at least
/// [`MIN_RUN`]), so the sums of a level fit one invocation's run.
pub fn scan_run(count: u64) -> u64 {
    if count <= MAX_SINGLE_RUN {
        count.max(1)
    } else {
        count.div_ceil(RUN_INVOCATIONS).max(MIN_RUN)
    }
}

/// Values per workgroup of a tile scan (keep in sync with `scan_tiles_common.glsl`).
pub const SCAN_TILE: u64 = 128 * 16;

/// Whether `device_type` scans in tiles (GPUs) rather than runs (CPU devices).
pub fn default_scan_tiles(device_type: vk::PhysicalDeviceType) -> bool {
    device_type != vk::PhysicalDeviceType::CPU
}

/// Push constants of the scan kernels, runs and tiles (`ScanPush` in
/// `scan_common.glsl` and `scan_tiles_common.glsl`; checked by `check_layout`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct ScanPush {
    /// The values, scanned in place.
    pub data: DeviceAddress,
    /// The per-invocation sums.
    pub sums: DeviceAddress,
    /// Number of values.
    pub count: u32,
    /// The apply kernels: whether `sums` holds scanned offsets (else all start at 0).
    pub has_sums: u32,
    /// Values per invocation of a run scan ([`scan_run`]; unread by tiles).
    pub run: u32,
    /// Padding.
    pub pad: u32,
}
crate::gpu::gpu_layout!(ScanPush, "ScanPush", [data, sums, count, has_sums, run, pad]);

/// The scan kernels and their scratch memory.
pub struct Scan {
    reduce: Arc<Kernel>,
    apply: Arc<Kernel>,
    /// Tiles of [`SCAN_TILE`] values a workgroup, else runs of [`scan_run`] an invocation.
    tiles: bool,
    /// Per-run or per-tile sums for each level above the first.
    levels: Vec<Buffer>,
    capacity: u64,
}

impl Scan {
    /// Builds the kernels of the device's shape ([`default_scan_tiles`]).
    pub fn new(device: &Device) -> Result<Self> {
        Self::with_tiles(device, default_scan_tiles(device.info().device_type))
    }

    /// Builds the kernels scanning in tiles (`true`) or runs (`false`), on any device.
    pub fn with_tiles(device: &Device, tiles: bool) -> Result<Self> {
        let (reduce, apply) = if tiles {
            (&kernels::SCAN_TILES_REDUCE, &kernels::SCAN_TILES_APPLY)
        } else {
            (&kernels::SCAN_REDUCE, &kernels::SCAN_APPLY)
        };
        Ok(Self {
            reduce: device.kernel(reduce, &KernelDecl::push::<ScanPush>(&[]))?,
            apply: device.kernel(apply, &KernelDecl::push::<ScanPush>(&[]))?,
            tiles,
            levels: Vec::new(),
            capacity: 0,
        })
    }

    /// Whether this scan works in tiles ([`Scan::with_tiles`]).
    pub fn tiles(&self) -> bool {
        self.tiles
    }

    /// Switches between tiles and runs, keeping scratch for the scans reserved so far.
    pub fn set_tiles(&mut self, device: &Device, tiles: bool) -> Result<()> {
        if tiles != self.tiles {
            let capacity = self.capacity;
            *self = Self::with_tiles(device, tiles)?;
            self.reserve(device, capacity)?;
        }
        Ok(())
    }

    /// Values one run or tile covers in a level of `count` values.
    fn span(&self, count: u64) -> u64 {
        if self.tiles {
            SCAN_TILE
        } else {
            scan_run(count)
        }
    }

    /// Makes sure scratch memory fits scans of up to `count` values.
    pub fn reserve(&mut self, device: &Device, count: u64) -> Result<()> {
        if count <= self.capacity {
            return Ok(());
        }
        self.levels.clear();
        // Each level's sums: tiles of a fixed size; runs at most RUN_INVOCATIONS sums
        // for any count (scan_run), which one invocation then scans alone.
        let mut n = count;
        while n > self.span(n) {
            n = if self.tiles { n.div_ceil(SCAN_TILE) } else { RUN_INVOCATIONS };
            self.levels.push(device.create_buffer(
                &format!("scan level {}", self.levels.len() + 1),
                n * 4,
                MemoryKind::Storage,
            )?);
        }
        self.capacity = count;
        Ok(())
    }

    /// GPU bytes of scratch memory held.
    pub(crate) fn scratch_bytes(&self) -> u64 {
        self.levels.iter().map(Buffer::size).sum()
    }

    /// Records an in-place exclusive scan of the first `count` u32 of `data`.
    /// Call [`Scan::reserve`] with at least `count` first.
    pub fn record<'a>(&'a self, rec: &mut Recording<'a>, data: &'a Buffer, count: u64) -> Result<()> {
        if count > self.capacity || count * 4 > data.size() || count > u64::from(u32::MAX) {
            return Err(crate::Error::invalid(
                format!("scan of {count} values"),
                format!("exceeds the scratch ({}) or buffer {} ({} bytes)", self.capacity, data.name(), data.size()),
            ));
        }
        let data = rec.addr(data)?;
        self.record_level(rec, data, count, 0)
    }

    fn record_level<'a>(
        &'a self,
        rec: &mut Recording<'a>,
        data: DeviceAddress,
        count: u64,
        level: usize,
    ) -> Result<()> {
        if count == 0 {
            return Ok(());
        }
        // Runs are invocations, tiles workgroups.
        let span = self.span(count);
        let parts = count.div_ceil(span);
        let grid = if self.tiles { Grid::Groups(parts) } else { Grid::Items(parts) };
        let sums = self.levels.get(level).filter(|_| parts > 1);
        let sums_address = rec.addr_or_null(sums)?;
        let push = ScanPush {
            data,
            sums: sums_address,
            count: count as u32,
            has_sums: u32::from(sums.is_some()),
            run: span as u32,
            pad: 0,
        };
        if sums.is_some() {
            rec.dispatch(&self.reduce, grid, &[], &push)?;
            self.record_level(rec, sums_address, parts, level + 1)?;
        }
        Ok(rec.dispatch(&self.apply, grid, &[], &push)?)
    }
}

/// CPU twin: exclusive prefix sum with wrapping addition.
pub fn exclusive_scan_cpu(values: &[u32]) -> Vec<u32> {
    let mut running = 0u32;
    values
        .iter()
        .map(|v| {
            let out = running;
            running = running.wrapping_add(*v);
            out
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::{scan_run, MAX_SINGLE_RUN, MIN_RUN, RUN_INVOCATIONS};

    /// Every count's runs: one run up to MAX_SINGLE_RUN values, else at most
    /// RUN_INVOCATIONS runs of at least MIN_RUN values, so the one level of
    /// sums `Scan::reserve` keeps fits any count and one invocation scans it.
    #[test]
    fn runs_take_at_most_two_levels_whatever_the_count() {
        let counts = (1..=70_000u64).chain([1 << 20, (1 << 24) + 3, u64::from(u32::MAX)]);
        for n in counts {
            let run = scan_run(n);
            let parts = n.div_ceil(run);
            if n <= MAX_SINGLE_RUN {
                assert_eq!((run, parts), (n, 1), "{n}");
            } else {
                assert!(run >= MIN_RUN && parts <= RUN_INVOCATIONS && parts <= MAX_SINGLE_RUN, "{n}: {run} x {parts}");
                assert!(parts > 1, "{n}");
            }
        }
    }
}
