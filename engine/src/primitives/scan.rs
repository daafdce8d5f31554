//! Exclusive prefix sum of `u32` on the GPU (reduce-then-scan).
//!
//! Every invocation owns `SCAN_ITEMS` consecutive values: `scan_reduce.comp`
//! sums them, the sums are scanned the same way (recursively, until one
//! invocation holds everything), and `scan_apply.comp` rewrites each run as
//! its exclusive prefix from the run's scanned sum. Invocations work alone in
//! registers: no shared memory (on CPU implementations such as lavapipe a
//! shared-memory access indexed by lane is a loop over the lanes; the earlier
//! shared-memory Hillis–Steele scan was several times slower there), no subgroup
//! operations, and no workgroup waits on another, so no forward-progress
//! guarantee is needed. Sums wrap modulo 2³² like `u32`.

use bytemuck::{Pod, Zeroable};
use std::sync::Arc;

use crate::error::Result;
use crate::gpu::{kernels, Buffer, Device, DeviceAddress, Grid, Kernel, KernelDecl, MemoryKind, Recording};

/// Values per invocation (keep in sync with `scan_common.glsl`).
pub(crate) const SCAN_ITEMS: u64 = 32;

/// Push constants of `scan_reduce.comp` and `scan_apply.comp` (`ScanPush` in
/// `scan_common.glsl`; checked by `check_layout`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct ScanPush {
    /// The values, scanned in place.
    pub data: DeviceAddress,
    /// The per-invocation sums.
    pub sums: DeviceAddress,
    /// Number of values.
    pub count: u32,
    /// `scan_apply.comp`: whether `sums` holds scanned offsets (else all start at 0).
    pub has_sums: u32,
}
crate::gpu::gpu_layout!(ScanPush, "ScanPush", [data, sums, count, has_sums]);

/// The scan kernels and their scratch memory.
pub struct Scan {
    reduce: Arc<Kernel>,
    apply: Arc<Kernel>,
    /// Per-invocation sums for each level above the first.
    levels: Vec<Buffer>,
    capacity: u64,
}

impl Scan {
    /// Builds the kernels.
    pub fn new(device: &Device) -> Result<Self> {
        Ok(Self {
            reduce: device.kernel(&kernels::SCAN_REDUCE, &KernelDecl::push::<ScanPush>(&[]))?,
            apply: device.kernel(&kernels::SCAN_APPLY, &KernelDecl::push::<ScanPush>(&[]))?,
            levels: Vec::new(),
            capacity: 0,
        })
    }

    /// Makes sure scratch memory fits scans of up to `count` values.
    pub fn reserve(&mut self, device: &Device, count: u64) -> Result<()> {
        if count <= self.capacity {
            return Ok(());
        }
        self.levels.clear();
        let mut n = count;
        while n > SCAN_ITEMS {
            n = n.div_ceil(SCAN_ITEMS);
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
        let invocations = count.div_ceil(SCAN_ITEMS);
        let sums = self.levels.get(level).filter(|_| invocations > 1);
        let sums_address = rec.addr_or_null(sums)?;
        let push = ScanPush { data, sums: sums_address, count: count as u32, has_sums: u32::from(sums.is_some()) };
        if sums.is_some() {
            rec.dispatch(&self.reduce, Grid::Items(invocations), &[], &push)?;
            self.record_level(rec, sums_address, invocations, level + 1)?;
        }
        Ok(rec.dispatch(&self.apply, Grid::Items(invocations), &[], &push)?)
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
