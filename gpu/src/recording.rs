//! Command recording, submission and per-stage GPU timestamps.
//!
//! A [`Recording`] borrows every buffer and kernel it uses until it is
//! submitted, so nothing it references can be dropped while recording. Every
//! command is preceded by a full compute/transfer memory barrier and the
//! recording ends with one toward the host: simple, always correct, and what
//! synchronization validation checks. Named stages bracket commands with
//! timestamps; [`Submission::wait`] returns their durations.

use std::marker::PhantomData;

use ash::vk;
use bytemuck::Pod;

use crate::buffer::{Buffer, Texels};
use crate::device::Device;
use crate::error::{vk_error, GpuError as Error, Result};
use crate::info::DeviceInfo;
use crate::kernel::Kernel;
use crate::layout::DeviceAddress;
use crate::shared::{lock, Garbage, Transient};
use crate::sync::HostSync;

/// Timestamp queries per recording: two per stage.
const MAX_QUERIES: u32 = 256;
/// Descriptor sets per pool; more pools are made as needed.
const SETS_PER_POOL: u32 = 64;
/// Storage-buffer descriptors per pool.
const DESCRIPTORS_PER_POOL: u32 = 512;

/// One descriptor binding of a dispatch.
#[derive(Clone, Copy, Debug)]
pub enum Binding<'a> {
    /// A storage or uniform buffer, bound whole.
    Buffer(&'a Buffer),
    /// Elements of a buffer seen through a texel-buffer view (`textureBuffer`).
    Texels(Texels<'a>),
}

impl<'a> From<&'a Buffer> for Binding<'a> {
    fn from(buffer: &'a Buffer) -> Self {
        Binding::Buffer(buffer)
    }
}

/// How many workgroups a dispatch runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Grid {
    /// One invocation per item: enough workgroups of the kernel's (1D) width,
    /// laid out as a 2D grid; shaders index items with `linear_index()`.
    Items(u64),
    /// This many workgroups laid out as a 2D grid (x first); shaders index
    /// them with `block_index()` from `common.glsl`.
    Groups(u64),
    /// Exactly this grid of workgroups.
    Exact([u32; 3]),
}

/// Checks a texel-buffer binding against the device's limits.
fn check_texels(info: &DeviceInfo, t: &Texels<'_>) -> std::result::Result<(), String> {
    let name = t.buffer.name();
    if !info.texel_formats.contains(&t.format) {
        return Err(format!("{:?} texel buffers are not supported on this device ({name})", t.format));
    }
    if t.elements > info.max_texel_buffer_elements {
        return Err(format!(
            "{} elements of {name} exceed maxTexelBufferElements ({})",
            t.elements, info.max_texel_buffer_elements
        ));
    }
    if t.offset % info.min_texel_buffer_offset_alignment != 0 {
        return Err(format!(
            "offset {} into {name} is not a multiple of minTexelBufferOffsetAlignment ({})",
            t.offset, info.min_texel_buffer_offset_alignment
        ));
    }
    let end = t.offset.checked_add(t.elements.max(1) * t.format.bytes());
    if end.is_none_or(|e| e > t.buffer.size().max(4)) {
        return Err(format!(
            "{} elements at offset {} overrun {name} ({} bytes)",
            t.elements,
            t.offset,
            t.buffer.size()
        ));
    }
    Ok(())
}

/// Time the GPU spent in one named stage.
#[derive(Clone, Debug, PartialEq)]
pub struct StageTime {
    /// The stage's name.
    pub name: String,
    /// Seconds between the stage's start and end timestamps.
    pub seconds: f64,
}

/// Per-stage GPU times of one submission.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Timings {
    /// Stages in recording order.
    pub stages: Vec<StageTime>,
}

impl std::fmt::Display for Timings {
    /// `name 1.2 ms, name 3.4 ms, ...` in recording order.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        for (i, s) in self.stages.iter().enumerate() {
            let sep = if i == 0 { "" } else { ", " };
            write!(f, "{sep}{} {:.1} ms", s.name, s.seconds * 1e3)?;
        }
        Ok(())
    }
}

impl Timings {
    /// Sum of all stage times.
    pub fn total_seconds(&self) -> f64 {
        self.stages.iter().map(|s| s.seconds).sum()
    }

    /// The time of the first stage with this name.
    pub fn get(&self, name: &str) -> Option<f64> {
        self.stages.iter().find(|s| s.name == name).map(|s| s.seconds)
    }
}

/// Commands being recorded. Consume it with [`Device::submit`] or [`Device::run`].
pub struct Recording<'a> {
    device: &'a Device,
    pub(crate) cmd: vk::CommandBuffer,
    transient: Option<Transient>,
    stages: Vec<(String, u32)>,
    open_stage: bool,
    next_query: u32,
    _uses: PhantomData<&'a Buffer>,
}

/// Work submitted to the GPU. Wait on it for completion and timings; dropping it
/// without waiting is allowed (its objects are freed when the GPU is done).
pub struct Submission {
    device: Device,
    seq: u64,
    transient: Option<Transient>,
    stages: Vec<(String, u32)>,
}

impl Device {
    /// Starts recording commands.
    pub fn begin(&self) -> Result<Recording<'_>> {
        let d = &self.shared.device;
        let pool_info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(self.shared.queue_family)
            .flags(vk::CommandPoolCreateFlags::TRANSIENT);
        // SAFETY: valid create info on a live device.
        let command_pool =
            unsafe { d.create_command_pool(&pool_info, None) }.map_err(vk_error("vkCreateCommandPool"))?;
        let mut transient =
            Transient { command_pool, descriptor_pools: Vec::new(), query_pool: None, buffer_views: Vec::new() };
        let alloc = vk::CommandBufferAllocateInfo::default()
            .command_pool(command_pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        // SAFETY: the pool was just created; on error it is destroyed.
        let cmd = match unsafe { d.allocate_command_buffers(&alloc) } {
            Ok(c) => c[0],
            Err(e) => {
                transient.destroy(d);
                return Err(vk_error("vkAllocateCommandBuffers")(e));
            }
        };
        let begin = vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
        // SAFETY: a fresh primary command buffer.
        if let Err(e) = unsafe { d.begin_command_buffer(cmd, &begin) } {
            transient.destroy(d);
            return Err(vk_error("vkBeginCommandBuffer")(e));
        }
        if self.shared.info.timestamp_valid_bits > 0 {
            let info = vk::QueryPoolCreateInfo::default().query_type(vk::QueryType::TIMESTAMP).query_count(MAX_QUERIES);
            // SAFETY: valid create info.
            match unsafe { d.create_query_pool(&info, None) } {
                Ok(q) => {
                    // SAFETY: recording state; the pool is new.
                    unsafe { d.cmd_reset_query_pool(cmd, q, 0, MAX_QUERIES) };
                    transient.query_pool = Some(q);
                }
                Err(e) => {
                    transient.destroy(d);
                    return Err(vk_error("vkCreateQueryPool")(e));
                }
            }
        }
        Ok(Recording {
            device: self,
            cmd,
            transient: Some(transient),
            stages: Vec::new(),
            open_stage: false,
            next_query: 0,
            _uses: PhantomData,
        })
    }

    /// Ends and submits a recording.
    pub fn submit(&self, rec: Recording<'_>) -> Result<Submission> {
        self.submit_synced(rec, &HostSync::default())
    }

    /// Ends and submits a recording that first waits on the host's `sync.wait`
    /// semaphores (at every stage) and signals `sync.signal` when done.
    pub fn submit_synced(&self, mut rec: Recording<'_>, sync: &HostSync) -> Result<Submission> {
        sync.check("the submission's semaphores")?;
        let shared = &self.shared;
        rec.end_stage();
        rec.barrier(vk::PipelineStageFlags::HOST, vk::AccessFlags::HOST_READ);
        let transient = rec.transient.take();
        let stages = std::mem::take(&mut rec.stages);
        let cmd = rec.cmd;
        let retire = |t: Option<Transient>| {
            if let Some(t) = t {
                shared.retire(Garbage::Transient(t));
            }
        };
        // SAFETY: recording state, begun in `begin`.
        if let Err(e) = unsafe { shared.device.end_command_buffer(cmd) } {
            retire(transient);
            return Err(vk_error("vkEndCommandBuffer")(e));
        }
        // SAFETY: valid create info.
        let fence = match unsafe { shared.device.create_fence(&vk::FenceCreateInfo::default(), None) } {
            Ok(f) => f,
            Err(e) => {
                retire(transient);
                return Err(vk_error("vkCreateFence")(e));
            }
        };
        let cmds = [cmd];
        let wait: Vec<vk::Semaphore> = sync.wait.iter().map(|w| w.semaphore).collect();
        let wait_values: Vec<u64> = sync.wait.iter().map(|w| w.value).collect();
        let wait_stages = vec![vk::PipelineStageFlags::ALL_COMMANDS; wait.len()];
        let signal: Vec<vk::Semaphore> = sync.signal.iter().map(|s| s.semaphore).collect();
        let signal_values: Vec<u64> = sync.signal.iter().map(|s| s.value).collect();
        let mut timeline = vk::TimelineSemaphoreSubmitInfo::default()
            .wait_semaphore_values(&wait_values)
            .signal_semaphore_values(&signal_values);
        let mut submit = vk::SubmitInfo::default()
            .command_buffers(&cmds)
            .wait_semaphores(&wait)
            .wait_dst_stage_mask(&wait_stages)
            .signal_semaphores(&signal);
        if !(wait.is_empty() && signal.is_empty()) {
            submit = submit.push_next(&mut timeline);
        }
        let mut tracker = lock(&shared.tracker);
        let queue = lock(&shared.queue);
        // SAFETY: the command buffer is executable, the fence unsignalled, the queue externally synchronized by its lock.
        let result = unsafe { shared.device.queue_submit(*queue, &[submit], fence) };
        drop(queue);
        if let Err(e) = result {
            drop(tracker);
            // SAFETY: the fence was never submitted.
            unsafe { shared.device.destroy_fence(fence, None) };
            retire(transient);
            return Err(vk_error("vkQueueSubmit")(e));
        }
        tracker.submitted += 1;
        let seq = tracker.submitted;
        tracker.in_flight.push_back((seq, fence));
        drop(tracker);
        Ok(Submission { device: self.clone(), seq, transient, stages })
    }

    /// Records with `f`, submits, waits, and returns the stage timings. `f` may
    /// fail with any error a [`GpuError`](crate::GpuError) converts into, so a
    /// caller's own error type passes through unchanged.
    pub fn run<'a, F, E>(&'a self, f: F) -> Result<Timings, E>
    where
        F: FnOnce(&mut Recording<'a>) -> Result<(), E>,
        E: From<Error>,
    {
        self.run_synced(&HostSync::default(), f)
    }

    /// [`Device::run`], with the submission waiting on and signalling the
    /// host's semaphores ([`Device::submit_synced`]).
    pub fn run_synced<'a, F, E>(&'a self, sync: &HostSync, f: F) -> Result<Timings, E>
    where
        F: FnOnce(&mut Recording<'a>) -> Result<(), E>,
        E: From<Error>,
    {
        let mut rec = self.begin()?;
        f(&mut rec)?;
        Ok(self.submit_synced(rec, sync)?.wait()?)
    }
}

impl Drop for Recording<'_> {
    fn drop(&mut self) {
        // A recording dropped without submission (e.g. on an error) was never
        // submitted, but earlier submissions may still run: retire as usual.
        if let Some(t) = self.transient.take() {
            self.device.shared.retire(Garbage::Transient(t));
        }
    }
}

impl Submission {
    /// Blocks until the GPU has finished this work; returns its stage timings.
    pub fn wait(mut self) -> Result<Timings> {
        let shared = &self.device.shared;
        shared.maintain(Some(self.seq))?;
        let mut timings = Timings::default();
        if let (Some(t), false) = (&self.transient, self.stages.is_empty()) {
            if let Some(pool) = t.query_pool {
                let count = self.stages.len() as u32 * 2;
                let mut ticks = vec![0u64; count as usize];
                // SAFETY: the submission finished; these queries were written by it.
                unsafe { shared.device.get_query_pool_results(pool, 0, &mut ticks, vk::QueryResultFlags::TYPE_64) }
                    .map_err(vk_error("vkGetQueryPoolResults"))?;
                let bits = shared.info.timestamp_valid_bits;
                let mask = if bits >= 64 { u64::MAX } else { (1u64 << bits) - 1 };
                let period = shared.info.timestamp_period_ns;
                for (name, q) in &self.stages {
                    let (a, b) = (ticks[*q as usize] & mask, ticks[*q as usize + 1] & mask);
                    let delta = b.wrapping_sub(a) & mask;
                    timings.stages.push(StageTime { name: name.clone(), seconds: delta as f64 * period * 1e-9 });
                }
            }
        }
        if let Some(t) = self.transient.take() {
            t.destroy(&shared.device);
        }
        Ok(timings)
    }
}

impl Drop for Submission {
    fn drop(&mut self) {
        if let Some(t) = self.transient.take() {
            self.device.shared.retire(Garbage::Transient(t));
        }
    }
}

impl<'a> Recording<'a> {
    /// The device this records for.
    pub fn device(&self) -> &'a Device {
        self.device
    }

    fn barrier(&mut self, dst_stage: vk::PipelineStageFlags, dst_access: vk::AccessFlags) {
        let barrier = vk::MemoryBarrier::default()
            .src_access_mask(vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::TRANSFER_WRITE)
            .dst_access_mask(dst_access);
        // SAFETY: recording state; a global memory barrier has no resource references.
        unsafe {
            self.device.shared.device.cmd_pipeline_barrier(
                self.cmd,
                vk::PipelineStageFlags::COMPUTE_SHADER | vk::PipelineStageFlags::TRANSFER,
                dst_stage,
                vk::DependencyFlags::empty(),
                &[barrier],
                &[],
                &[],
            );
        }
    }

    pub(crate) fn before_command(&mut self) {
        self.barrier(
            vk::PipelineStageFlags::COMPUTE_SHADER | vk::PipelineStageFlags::TRANSFER,
            vk::AccessFlags::SHADER_READ
                | vk::AccessFlags::UNIFORM_READ
                | vk::AccessFlags::SHADER_WRITE
                | vk::AccessFlags::TRANSFER_READ
                | vk::AccessFlags::TRANSFER_WRITE,
        );
    }

    fn timestamp(&mut self) -> Option<u32> {
        let pool = self.transient.as_ref()?.query_pool?;
        if self.next_query >= MAX_QUERIES {
            return None;
        }
        let q = self.next_query;
        self.next_query += 1;
        // SAFETY: the query was reset at the start of this command buffer.
        unsafe {
            self.device.shared.device.cmd_write_timestamp(self.cmd, vk::PipelineStageFlags::BOTTOM_OF_PIPE, pool, q);
        }
        Some(q)
    }

    /// Starts a named, timed stage (ending any open one). Stages beyond the
    /// query capacity, or on devices without timestamps, go untimed.
    pub fn begin_stage(&mut self, name: &str) {
        self.end_stage();
        if self.next_query + 2 > MAX_QUERIES {
            return;
        }
        if let Some(q) = self.timestamp() {
            self.stages.push((name.to_string(), q));
            self.open_stage = true;
        }
    }

    /// Stages begun so far in this recording (each becomes one
    /// [`StageTime`], in order, unless the recording ran out of timestamp
    /// queries, in which case later stages are neither counted nor timed):
    /// callers that record several frames split [`Timings`] at these marks.
    pub fn stages_begun(&self) -> usize {
        self.stages.len()
    }

    /// Ends the open stage, if any.
    pub fn end_stage(&mut self) {
        if self.open_stage {
            let _ = self.timestamp();
            self.open_stage = false;
        }
    }

    /// Sets every 32-bit word of `buffer` to `word`.
    pub fn fill(&mut self, buffer: &'a Buffer, word: u32) -> Result<()> {
        self.check_device(buffer)?;
        self.before_command();
        // SAFETY: recording state; the buffer is a live TRANSFER_DST buffer of this device.
        unsafe { self.device.shared.device.cmd_fill_buffer(self.cmd, buffer.raw, 0, buffer.used_bytes(), word) };
        Ok(())
    }

    /// Sets the 32-bit words `first..first + count` of `buffer` to `word`
    /// (where a kernel writes every other word itself).
    pub fn fill_words(&mut self, buffer: &'a Buffer, first: u64, count: u64, word: u32) -> Result<()> {
        self.check_device(buffer)?;
        let end = first.checked_add(count).and_then(|e| e.checked_mul(4));
        if count == 0 || end.is_none_or(|e| e > buffer.used_bytes()) {
            return Err(Error::invalid(
                format!("filling words {first}..{first}+{count} of buffer '{}'", buffer.name()),
                format!("needs 1 or more words within its {} bytes", buffer.used_bytes()),
            ));
        }
        self.before_command();
        // SAFETY: recording state; the buffer is a live TRANSFER_DST buffer of this device, the range checked above.
        unsafe { self.device.shared.device.cmd_fill_buffer(self.cmd, buffer.raw, 4 * first, 4 * count, word) };
        Ok(())
    }

    /// Two fills of one buffer with no barrier between them: a write-after-write
    /// hazard that synchronization validation must report. Tests only.
    #[doc(hidden)]
    pub fn fill_twice_without_barrier(&mut self, buffer: &'a Buffer) -> Result<()> {
        self.fill(buffer, 0)?;
        // SAFETY: a valid command; the missing barrier is the point (a data race on a scratch buffer).
        unsafe { self.device.shared.device.cmd_fill_buffer(self.cmd, buffer.raw, 0, vk::WHOLE_SIZE, 1) };
        Ok(())
    }

    /// Copies `size` bytes between buffers.
    pub fn copy(
        &mut self,
        src: &'a Buffer,
        src_offset: u64,
        dst: &'a Buffer,
        dst_offset: u64,
        size: u64,
    ) -> Result<()> {
        self.check_device(src)?;
        self.check_device(dst)?;
        let fits = |off: u64, b: &Buffer| off.checked_add(size).is_some_and(|e| e <= b.size());
        if !fits(src_offset, src) || !fits(dst_offset, dst) {
            return Err(Error::invalid(
                "copy",
                format!(
                    "{size} bytes from {}+{src_offset} to {}+{dst_offset} is out of bounds",
                    src.name(),
                    dst.name()
                ),
            ));
        }
        if size == 0 {
            return Ok(());
        }
        self.before_command();
        let region = vk::BufferCopy { src_offset, dst_offset, size };
        // SAFETY: in-bounds region between live buffers of this device.
        unsafe { self.device.shared.device.cmd_copy_buffer(self.cmd, src.raw, dst.raw, &[region]) };
        Ok(())
    }

    pub(crate) fn check_device(&self, buffer: &Buffer) -> Result<()> {
        if std::sync::Arc::ptr_eq(&buffer.shared, &self.device.shared) {
            Ok(())
        } else {
            Err(Error::invalid(format!("buffer {}", buffer.name()), "belongs to another device"))
        }
    }

    /// Records one dispatch: `kernel` over `grid`, with `bindings` bound in
    /// order (set 0, bindings 0..n; buffers or texel-buffer views, each of the
    /// kind the shader declares) and `push` as the push constants. The one
    /// dispatch entry point.
    pub fn dispatch<P: Pod>(
        &mut self,
        kernel: &'a Kernel,
        grid: Grid,
        bindings: &[Binding<'a>],
        push: &P,
    ) -> Result<()> {
        let limits = self.device.shared.info.max_workgroup_count;
        let groups = match grid {
            Grid::Exact(groups) => groups,
            Grid::Groups(count) => grid_1d(count, 1, limits).ok_or_else(|| Error::Kernel {
                kernel: kernel.info.name,
                message: format!("{count} workgroups exceed the dispatch limits"),
            })?,
            Grid::Items(count) => {
                if kernel.workgroup_size[1] * kernel.workgroup_size[2] != 1 {
                    return Err(Error::Kernel {
                        kernel: kernel.info.name,
                        message: format!("workgroup size {:?} is not one-dimensional", kernel.workgroup_size),
                    });
                }
                grid_1d(count, kernel.workgroup_size[0], limits).ok_or_else(|| Error::Kernel {
                    kernel: kernel.info.name,
                    message: format!("{count} invocations exceed the dispatch limits"),
                })?
            }
        };
        self.record_dispatch(kernel, bindings, push, groups)
    }

    fn record_dispatch<P: Pod>(
        &mut self,
        kernel: &'a Kernel,
        bindings: &[Binding<'a>],
        push: &P,
        groups: [u32; 3],
    ) -> Result<()> {
        let name = kernel.info.name;
        let err = |message: String| Error::Kernel { kernel: name, message };
        if !std::sync::Arc::ptr_eq(&kernel.shared, &self.device.shared) {
            return Err(err("belongs to another device".into()));
        }
        if bindings.len() != kernel.info.bindings.len() {
            return Err(err(format!(
                "{} buffers given, {} bindings declared",
                bindings.len(),
                kernel.info.bindings.len()
            )));
        }
        if std::mem::size_of::<P>() != kernel.push_constant_size as usize {
            return Err(err(format!(
                "push constants of {} bytes given, the kernel takes {}",
                std::mem::size_of::<P>(),
                kernel.push_constant_size
            )));
        }
        let info = &self.device.shared.info;
        let limits = info.max_workgroup_count;
        if groups.iter().zip(limits).any(|(g, l)| *g > l) {
            return Err(err(format!("{groups:?} workgroups exceed the device limit {limits:?}")));
        }
        let max_range = info.max_storage_buffer_range;
        for (i, binding) in bindings.iter().enumerate() {
            let texel_kind = kernel.descriptor_types[i] == vk::DescriptorType::UNIFORM_TEXEL_BUFFER;
            match binding {
                Binding::Buffer(b) => {
                    self.check_device(b)?;
                    if texel_kind {
                        return Err(err(format!("binding {i} is a texel buffer; buffer {} given", b.name())));
                    }
                    if b.size().max(4) > max_range {
                        return Err(err(format!(
                            "buffer {} ({} bytes) exceeds maxStorageBufferRange ({max_range}); reach it by device address",
                            b.name(),
                            b.size()
                        )));
                    }
                }
                Binding::Texels(t) => {
                    self.check_device(t.buffer)?;
                    if !texel_kind {
                        return Err(err(format!("binding {i} is a buffer block; texels of {} given", t.buffer.name())));
                    }
                    check_texels(info, t).map_err(err)?;
                }
            }
        }
        if groups.contains(&0) {
            return Ok(());
        }
        let d = &self.device.shared.device;
        let set = match kernel.set_layout {
            Some(layout) => Some(self.allocate_set(layout, bindings.len() as u32)?),
            None => None,
        };
        if let Some(set) = set {
            let mut views = Vec::new();
            for binding in bindings {
                if let Binding::Texels(t) = binding {
                    let create = vk::BufferViewCreateInfo::default()
                        .buffer(t.buffer.raw)
                        .format(t.format.vk())
                        .offset(t.offset)
                        .range(t.elements.max(1) * t.format.bytes());
                    // SAFETY: `check_texels` checked the range, alignment and format against the device.
                    let view =
                        unsafe { d.create_buffer_view(&create, None) }.map_err(vk_error("vkCreateBufferView"))?;
                    self.transient
                        .as_mut()
                        .ok_or_else(|| Error::invalid("recording", "already submitted"))?
                        .buffer_views
                        .push(view);
                    views.push([view]);
                }
            }
            let infos: Vec<[vk::DescriptorBufferInfo; 1]> = bindings
                .iter()
                .map(|b| match b {
                    Binding::Buffer(b) => {
                        [vk::DescriptorBufferInfo { buffer: b.raw, offset: 0, range: b.used_bytes() }]
                    }
                    Binding::Texels(_) => [vk::DescriptorBufferInfo::default()],
                })
                .collect();
            let mut next_view = views.iter();
            let writes: Vec<vk::WriteDescriptorSet<'_>> = bindings
                .iter()
                .zip(&infos)
                .enumerate()
                .map(|(i, (b, info))| {
                    let write = vk::WriteDescriptorSet::default()
                        .dst_set(set)
                        .dst_binding(i as u32)
                        .descriptor_type(kernel.descriptor_types[i]);
                    match b {
                        // One view per texel binding, made above in the same order.
                        Binding::Texels(_) => match next_view.next() {
                            Some(view) => write.texel_buffer_view(view),
                            None => write,
                        },
                        Binding::Buffer(_) => write.buffer_info(info),
                    }
                })
                .collect();
            // SAFETY: the set was allocated with this layout; buffers and views are live.
            unsafe { d.update_descriptor_sets(&writes, &[]) };
        }
        self.before_command();
        // SAFETY: recording state; pipeline, layout and set belong to this device and are kept
        // alive by the borrow of `kernel` until submission and by deferred destruction after.
        unsafe {
            d.cmd_bind_pipeline(self.cmd, vk::PipelineBindPoint::COMPUTE, kernel.pipeline);
            if let Some(set) = set {
                d.cmd_bind_descriptor_sets(self.cmd, vk::PipelineBindPoint::COMPUTE, kernel.layout, 0, &[set], &[]);
            }
            if kernel.push_constant_size > 0 {
                d.cmd_push_constants(
                    self.cmd,
                    kernel.layout,
                    vk::ShaderStageFlags::COMPUTE,
                    0,
                    bytemuck::bytes_of(push),
                );
            }
            d.cmd_dispatch(self.cmd, groups[0], groups[1], groups[2]);
        }
        Ok(())
    }

    /// The device address of a storage `buffer`, for a uniform or push-constant
    /// block; the recording keeps `buffer` borrowed until it is submitted, so
    /// it cannot be dropped while a kernel may still follow the address.
    pub fn addr(&mut self, buffer: &'a Buffer) -> Result<DeviceAddress> {
        self.check_device(buffer)?;
        if buffer.device_address() == 0 {
            return Err(Error::invalid(
                format!("buffer {}", buffer.name()),
                "has no device address (not a storage buffer)",
            ));
        }
        Ok(DeviceAddress::new(buffer.device_address()))
    }

    /// The device address `offset` bytes into `buffer` (a level of a mip chain
    /// packed in one buffer), borrowed as [`Recording::addr`] borrows. An
    /// offset equal to the size is the end of the buffer (an empty region).
    pub fn addr_at(&mut self, buffer: &'a Buffer, offset: u64) -> Result<DeviceAddress> {
        let base = self.addr(buffer)?;
        if offset > buffer.size() {
            return Err(Error::invalid(
                format!("buffer {} ({} bytes)", buffer.name(), buffer.size()),
                format!("offset {offset} is past its end"),
            ));
        }
        Ok(base.offset(offset))
    }

    /// [`Recording::addr`] of an optional buffer; [`DeviceAddress::NULL`] for none.
    pub fn addr_or_null(&mut self, buffer: Option<&'a Buffer>) -> Result<DeviceAddress> {
        buffer.map_or(Ok(DeviceAddress::NULL), |b| self.addr(b))
    }

    /// Writes `data` into `buffer` at byte `offset` as a recorded command
    /// (`vkCmdUpdateBuffer`: at most 65536 bytes, offset and size multiples of
    /// 4), ordered with the commands around it. Uniform blocks that carry
    /// addresses from [`Recording::addr`] are written this way.
    pub fn update<T: Pod>(&mut self, buffer: &'a Buffer, offset: u64, data: &T) -> Result<()> {
        self.update_bytes(buffer, offset, bytemuck::bytes_of(data))
    }

    /// [`Recording::update`] with raw bytes.
    pub fn update_bytes(&mut self, buffer: &'a Buffer, offset: u64, bytes: &[u8]) -> Result<()> {
        self.check_device(buffer)?;
        let size = bytes.len() as u64;
        let fits = offset.checked_add(size).is_some_and(|e| e <= buffer.size());
        if !fits || size == 0 || size > 65536 || size % 4 != 0 || offset % 4 != 0 {
            return Err(Error::invalid(
                format!("buffer {} ({} bytes)", buffer.name(), buffer.size()),
                format!("an update of {size} bytes at {offset} is out of bounds, empty, over 65536 bytes or unaligned"),
            ));
        }
        self.before_command();
        // SAFETY: recording state; in-bounds, 4-aligned update of a live TRANSFER_DST buffer of this device.
        unsafe { self.device.shared.device.cmd_update_buffer(self.cmd, buffer.raw, offset, bytes) };
        Ok(())
    }

    fn allocate_set(&mut self, layout: vk::DescriptorSetLayout, descriptors: u32) -> Result<vk::DescriptorSet> {
        let d = &self.device.shared.device;
        let transient = self.transient.as_mut().ok_or_else(|| Error::invalid("recording", "already submitted"))?;
        if let Some(&pool) = transient.descriptor_pools.last() {
            let layouts = [layout];
            let info = vk::DescriptorSetAllocateInfo::default().descriptor_pool(pool).set_layouts(&layouts);
            // SAFETY: pool and layout are live objects of this device.
            match unsafe { d.allocate_descriptor_sets(&info) } {
                Ok(sets) => return Ok(sets[0]),
                Err(vk::Result::ERROR_OUT_OF_POOL_MEMORY | vk::Result::ERROR_FRAGMENTED_POOL) => {}
                Err(e) => return Err(vk_error("vkAllocateDescriptorSets")(e)),
            }
        }
        let sizes = [
            vk::DescriptorPoolSize {
                ty: vk::DescriptorType::STORAGE_BUFFER,
                descriptor_count: DESCRIPTORS_PER_POOL.max(descriptors),
            },
            vk::DescriptorPoolSize { ty: vk::DescriptorType::UNIFORM_BUFFER, descriptor_count: SETS_PER_POOL },
            vk::DescriptorPoolSize {
                ty: vk::DescriptorType::UNIFORM_TEXEL_BUFFER,
                descriptor_count: DESCRIPTORS_PER_POOL.max(descriptors),
            },
        ];
        let info = vk::DescriptorPoolCreateInfo::default().max_sets(SETS_PER_POOL).pool_sizes(&sizes);
        // SAFETY: valid create info.
        let pool = unsafe { d.create_descriptor_pool(&info, None) }.map_err(vk_error("vkCreateDescriptorPool"))?;
        transient.descriptor_pools.push(pool);
        let layouts = [layout];
        let info = vk::DescriptorSetAllocateInfo::default().descriptor_pool(pool).set_layouts(&layouts);
        // SAFETY: a fresh pool sized for at least this set.
        let sets = unsafe { d.allocate_descriptor_sets(&info) }.map_err(vk_error("vkAllocateDescriptorSets"))?;
        Ok(sets[0])
    }
}

/// Workgroup grid for `count` invocations of `width`-wide workgroups: x first,
/// then as few rows in y as `limits` allow, the rows as even as whole groups
/// make them, so past `limits[0]` groups the grid has fewer than one group
/// per row to spare. A spare group is a launch that finds no item, and on a
/// CPU device each launch costs time: full rows of `limits[0]` would leave
/// most of the last row spare. `None` when even that exceeds `limits`.
pub fn grid_1d(count: u64, width: u32, limits: [u32; 3]) -> Option<[u32; 3]> {
    let groups = count.div_ceil(u64::from(width.max(1)));
    if groups == 0 {
        return Some([0, 1, 1]);
    }
    let gy = groups.div_ceil(u64::from(limits[0].max(1)));
    let gx = groups.div_ceil(gy);
    (gy <= u64::from(limits[1])).then_some([gx as u32, gy as u32, 1])
}
