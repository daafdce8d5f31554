//! The state every GPU object shares: instance, device, queue, allocator,
//! the validation log, and the garbage that waits for submissions to finish.
//!
//! A leaf: garbage is raw Vulkan handles, so this module imports no other
//! object module (buffers, kernels and recordings import it, never the reverse).

use std::any::Any;
use std::collections::{HashMap, VecDeque};
use std::ffi::{c_void, CStr};
use std::mem::ManuallyDrop;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};

use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme, Allocator};
use gpu_allocator::MemoryLocation;
use srug_spirv::BindingKind;

use crate::error::{vk_error, GpuError, Result};
use crate::info::DeviceInfo;

/// Per-recording Vulkan objects, destroyed once its submission has finished.
pub(crate) struct Transient {
    pub(crate) command_pool: vk::CommandPool,
    pub(crate) descriptor_pools: Vec<vk::DescriptorPool>,
    pub(crate) query_pool: Option<vk::QueryPool>,
    pub(crate) buffer_views: Vec<vk::BufferView>,
}

impl Transient {
    pub(crate) fn destroy(self, device: &ash::Device) {
        // SAFETY: the caller guarantees the GPU has finished with these objects.
        unsafe {
            device.destroy_command_pool(self.command_pool, None);
            for p in self.descriptor_pools {
                device.destroy_descriptor_pool(p, None);
            }
            for v in self.buffer_views {
                device.destroy_buffer_view(v, None);
            }
            if let Some(q) = self.query_pool {
                device.destroy_query_pool(q, None);
            }
        }
    }
}

/// Collects what the validation layer says.
#[derive(Default)]
pub(crate) struct ValidationLog {
    pub(crate) messages: Mutex<Vec<String>>,
}

/// Something to destroy once the GPU has finished the submission it may be used in.
pub(crate) enum Garbage {
    /// A buffer, its memory, and what lets it be reused ([`BufferPool`]).
    Buffer(vk::Buffer, Allocation, PooledKey),
    Image(vk::Image, Allocation),
    /// An exported image and its dedicated memory (not srug's allocator's).
    ExportedImage(vk::Image, vk::DeviceMemory),
    Semaphore(vk::Semaphore),
    Pipeline {
        pipeline: vk::Pipeline,
        layout: vk::PipelineLayout,
        set_layout: Option<vk::DescriptorSetLayout>,
    },
    Transient(Transient),
}

/// What a freed buffer can be reused as: its usage (which says its memory
/// kind), its device address (0 for non-storage buffers) and the Vulkan
/// buffer's size.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PooledKey {
    pub(crate) usage: vk::BufferUsageFlags,
    pub(crate) address: u64,
    pub(crate) vk_size: u64,
}

/// A freed buffer kept for reuse.
pub(crate) struct PooledBuffer {
    pub(crate) raw: vk::Buffer,
    pub(crate) allocation: Allocation,
    pub(crate) key: PooledKey,
}

/// Buffers the GPU is done with, kept (oldest first) so that the next buffer
/// of the same kind and about the same size takes one instead of new memory.
/// On lavapipe device memory is host memory, and gpu-allocator returns an
/// emptied 256 MiB block (all but the last) to the system: the next batch's
/// buffers were then faulted in and zeroed page by page by the first kernel
/// writing them. Contents are undefined, as Vulkan's fresh memory is.
/// A fresh allocation first frees pooled buffers, oldest first, until in
/// use and pooled stay within the most ever in use (staging: plus a little
/// headroom; all of them past it: [`Shared::trim_pool_for`]).
pub(crate) struct BufferPool {
    pub(crate) items: VecDeque<PooledBuffer>,
    pub(crate) bytes: u64,
    /// Most bytes kept ([`pool_limit`]); a buffer over half of it is never kept.
    pub(crate) limit: u64,
}

/// The pool's limit on a device whose largest device-local heap has
/// `heap_bytes`: an eighth of it, 256 MiB to 4 GiB (a 10M-Gaussian frame's
/// splat records alone take 640 MB).
pub(crate) fn pool_limit(heap_bytes: u64) -> u64 {
    (heap_bytes / 8).clamp(256 << 20, 4 << 30)
}

/// Bytes the device's pool of freed buffers may hold beyond the most ever in
/// use at once when a host-visible (staging) buffer is freshly allocated
/// (below that mark, a fresh allocation frees pooled buffers, oldest first,
/// until in use and pooled stay within it): room for a streamed load's
/// staging buffers of every size (one per attribute), which would otherwise
/// be freed and faulted in again for every block.
pub const POOL_HEADROOM_BYTES: u64 = 32 << 20;

/// A pooled buffer may be up to this much larger than asked for (as a fraction, 1/4).
const POOL_SLACK_DIVISOR: u64 = 4;

impl BufferPool {
    /// An empty pool keeping at most `limit` bytes.
    pub(crate) fn new(limit: u64) -> Self {
        Self { items: VecDeque::new(), bytes: 0, limit }
    }

    /// The smallest pooled buffer of `usage` of `vk_size` bytes up to a quarter more.
    pub(crate) fn take(&mut self, usage: vk::BufferUsageFlags, vk_size: u64) -> Option<PooledBuffer> {
        let limit = vk_size + vk_size / POOL_SLACK_DIVISOR;
        let best = self
            .items
            .iter()
            .enumerate()
            .filter(|(_, b)| b.key.usage == usage && (vk_size..=limit).contains(&b.key.vk_size))
            .min_by_key(|(_, b)| b.key.vk_size)
            .map(|(i, _)| i)?;
        let item = self.items.remove(best)?;
        self.bytes -= item.allocation.size();
        Some(item)
    }
}

/// Submissions in flight and resources waiting for them.
#[derive(Default)]
pub(crate) struct Tracker {
    /// Sequence number of the latest submission.
    pub(crate) submitted: u64,
    /// Every submission up to this one has completed.
    pub(crate) completed: u64,
    pub(crate) in_flight: VecDeque<(u64, vk::Fence)>,
    pub(crate) garbage: Vec<(u64, Garbage)>,
}

/// State shared by the device and every object made from it. Objects hold an
/// `Arc` of it, so the device outlives them all.
pub(crate) struct Shared {
    pub(crate) _entry: ash::Entry,
    pub(crate) instance: ash::Instance,
    pub(crate) debug: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
    pub(crate) validation_log: Option<Box<ValidationLog>>,
    pub(crate) device: ash::Device,
    /// Whether srug created the device and instance (and so destroys them);
    /// false for a host's ([`crate::Device::from_raw`]).
    pub(crate) owns_device: bool,
    pub(crate) physical_device: vk::PhysicalDevice,
    pub(crate) queue: Mutex<vk::Queue>,
    pub(crate) queue_family: u32,
    pub(crate) allocator: Mutex<ManuallyDrop<Allocator>>,
    pub(crate) tracker: Mutex<Tracker>,
    pub(crate) info: DeviceInfo,
    pub(crate) current_bytes: AtomicU64,
    pub(crate) peak_bytes: AtomicU64,
    /// Most bytes allocated at once since the device was made (never reset,
    /// unlike `peak_bytes`): a fresh allocation frees pooled buffers so that
    /// in use and pooled stay near it ([`Shared::trim_pool_for`]).
    pub(crate) high_water_bytes: AtomicU64,
    /// Allocations that took new memory rather than a pooled buffer.
    pub(crate) fresh_allocations: AtomicU64,
    /// Freed buffers kept for reuse.
    pub(crate) pool: Mutex<BufferPool>,
    /// Every kernel built through `Device::kernel`, by what makes it that
    /// pipeline. Type-erased so this leaf does not import `kernel`; cleared
    /// when the last `Device` handle drops (`CacheOwner`), which breaks the
    /// kernels' references back to this state.
    pub(crate) kernel_cache: Mutex<HashMap<KernelKey, Arc<dyn Any + Send + Sync>>>,
}

/// What makes two kernels one pipeline: the SPIR-V (by kernel name), the
/// declared bindings and push-constant size, and the specialization.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub(crate) struct KernelKey {
    pub(crate) name: &'static str,
    pub(crate) bindings: Vec<BindingKind>,
    pub(crate) push_constant_size: usize,
    pub(crate) specialization: Vec<(u32, u32)>,
}

/// Locks a mutex, recovering the data if a panicking thread poisoned it.
pub(crate) fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

impl Shared {
    /// Memory for a resource srug just created: allocated to `requirements`
    /// at `location`, bound with `bind` (memory, offset; `bind_call` names it
    /// in errors) and counted in the memory use. On failure the allocation is
    /// freed and `discard` destroys the resource. `what` names it in errors.
    #[allow(clippy::too_many_arguments, reason = "one allocation's inputs and its two callbacks")]
    pub(crate) fn allocate_bound(
        &self,
        what: &str,
        name: &str,
        requirements: vk::MemoryRequirements,
        location: MemoryLocation,
        linear: bool,
        bind_call: &'static str,
        bind: impl FnOnce(vk::DeviceMemory, u64) -> std::result::Result<(), vk::Result>,
        discard: impl FnOnce(),
    ) -> Result<Allocation> {
        let desc = AllocationCreateDesc {
            name,
            requirements,
            location,
            linear,
            allocation_scheme: AllocationScheme::GpuAllocatorManaged,
        };
        // Host-visible buffers (staging) may keep the pool a little past the mark.
        let headroom = if location == MemoryLocation::GpuOnly { 0 } else { POOL_HEADROOM_BYTES };
        self.trim_pool_for(requirements.size, name, headroom);
        let mut result = lock(&self.allocator).allocate(&desc);
        // Out of memory with freed buffers still kept: free them and try once more.
        if result.is_err() && self.drain_pool() > 0 {
            result = lock(&self.allocator).allocate(&desc);
        }
        let allocation = match result {
            Ok(a) => a,
            Err(e) => {
                discard();
                return Err(GpuError::OutOfMemory(format!("{what}: {e}")));
            }
        };
        // SAFETY: the memory stays allocated while the resource it is bound to lives
        // (it is freed with the resource, through `Garbage`).
        let memory = unsafe { allocation.memory() };
        if let Err(e) = bind(memory, allocation.offset()) {
            let _ = lock(&self.allocator).free(allocation);
            discard();
            return Err(vk_error(bind_call)(e));
        }
        let bytes = allocation.size();
        log::trace!("fresh allocation of {bytes} bytes for {name}");
        self.count_allocated(bytes);
        self.fresh_allocations.fetch_add(1, Ordering::Relaxed);
        Ok(allocation)
    }

    /// Counts `bytes` more allocated (fresh or taken from the pool) in the
    /// current use, its peak and the high-water mark.
    pub(crate) fn count_allocated(&self, bytes: u64) {
        let now = self.current_bytes.fetch_add(bytes, Ordering::Relaxed) + bytes;
        self.peak_bytes.fetch_max(now, Ordering::Relaxed);
        self.high_water_bytes.fetch_max(now, Ordering::Relaxed);
    }

    /// Before `bytes` named `name` are freshly allocated: when that puts
    /// more memory in use than was ever allocated at once, frees every pooled
    /// buffer (what the pool holds would only sit beside the larger work);
    /// below that mark, frees pooled buffers, oldest first, until in use,
    /// pooled and the new buffer stay within it plus `headroom`
    /// ([`POOL_HEADROOM_BYTES`] for staging, else 0).
    /// The pool keeps what work of the sizes seen so far will take again,
    /// but work whose sizes change (compacted splat records, a view seeing
    /// less) would otherwise leave the old sizes pooled beside the new.
    pub(crate) fn trim_pool_for(&self, bytes: u64, name: &str, headroom: u64) {
        let after = self.current_bytes.load(Ordering::Relaxed).saturating_add(bytes);
        let most = self.high_water_bytes.load(Ordering::Relaxed);
        let room = if after > most { 0 } else { (most + headroom).saturating_sub(after) };
        let evicted = {
            let mut pool = lock(&self.pool);
            let mut evicted = Vec::new();
            while pool.bytes > room {
                let Some(old) = pool.items.pop_front() else { break };
                pool.bytes -= old.allocation.size();
                evicted.push(old);
            }
            evicted
        };
        for old in evicted {
            log::trace!("pooled buffer of {} bytes freed for {name} ({bytes} bytes)", old.allocation.size());
            self.free_buffer(old.raw, old.allocation);
        }
    }

    /// Destroys a garbage item now. The caller guarantees the GPU is done with it.
    fn destroy(&self, item: Garbage) {
        match item {
            Garbage::Buffer(raw, allocation, key) => {
                self.current_bytes.fetch_sub(allocation.size(), Ordering::Relaxed);
                // Kept (evicting the oldest past the limit) unless over half the limit;
                // what is freed is freed outside the pool's lock.
                let freed = {
                    let mut pool = lock(&self.pool);
                    if allocation.size() <= pool.limit / 2 {
                        pool.bytes += allocation.size();
                        pool.items.push_back(PooledBuffer { raw, allocation, key });
                        let mut evicted = Vec::new();
                        while pool.bytes > pool.limit {
                            let Some(old) = pool.items.pop_front() else { break };
                            pool.bytes -= old.allocation.size();
                            evicted.push(old);
                        }
                        evicted
                    } else {
                        vec![PooledBuffer { raw, allocation, key }]
                    }
                };
                for old in freed {
                    self.free_buffer(old.raw, old.allocation);
                }
            }
            Garbage::Image(image, allocation) => {
                let size = allocation.size();
                if let Err(e) = lock(&self.allocator).free(allocation) {
                    log::error!("freeing GPU memory failed: {e}");
                }
                self.current_bytes.fetch_sub(size, Ordering::Relaxed);
                // SAFETY: the image belongs to this device and no submission uses it any more.
                unsafe { self.device.destroy_image(image, None) };
            }
            Garbage::ExportedImage(image, memory) => {
                // SAFETY: as above; the memory was allocated for this image alone.
                unsafe {
                    self.device.destroy_image(image, None);
                    self.device.free_memory(memory, None);
                }
            }
            Garbage::Semaphore(semaphore) => {
                // SAFETY: as above.
                unsafe { self.device.destroy_semaphore(semaphore, None) };
            }
            Garbage::Pipeline { pipeline, layout, set_layout } => {
                // SAFETY: as above; the objects were created on this device.
                unsafe {
                    self.device.destroy_pipeline(pipeline, None);
                    self.device.destroy_pipeline_layout(layout, None);
                    if let Some(s) = set_layout {
                        self.device.destroy_descriptor_set_layout(s, None);
                    }
                }
            }
            Garbage::Transient(t) => t.destroy(&self.device),
        }
    }

    /// Frees a buffer's memory and destroys it. The caller guarantees the GPU is done with it.
    fn free_buffer(&self, raw: vk::Buffer, allocation: Allocation) {
        if let Err(e) = lock(&self.allocator).free(allocation) {
            log::error!("freeing GPU memory failed: {e}");
        }
        // SAFETY: the buffer belongs to this device and no submission uses it any more.
        unsafe { self.device.destroy_buffer(raw, None) };
    }

    /// Frees every pooled buffer; returns the bytes released.
    pub(crate) fn drain_pool(&self) -> u64 {
        let items = {
            let mut pool = lock(&self.pool);
            pool.bytes = 0;
            std::mem::take(&mut pool.items)
        };
        let mut bytes = 0;
        for item in items {
            bytes += item.allocation.size();
            self.free_buffer(item.raw, item.allocation);
        }
        bytes
    }

    /// Queues `item` for destruction after every submission made so far.
    pub(crate) fn retire(&self, item: Garbage) {
        let mut tracker = lock(&self.tracker);
        if tracker.submitted <= tracker.completed {
            drop(tracker);
            self.destroy(item);
        } else {
            let seq = tracker.submitted;
            tracker.garbage.push((seq, item));
        }
    }

    /// Records finished submissions and frees what waited on them. With
    /// `wait_for`, first blocks until that submission has finished.
    pub(crate) fn maintain(&self, wait_for: Option<u64>) -> Result<()> {
        let mut freed = Vec::new();
        {
            let mut tracker = lock(&self.tracker);
            while let Some(&(seq, fence)) = tracker.in_flight.front() {
                let must_wait = wait_for.is_some_and(|w| seq <= w);
                // SAFETY: the fence belongs to this device and is not destroyed until popped below.
                let done = unsafe {
                    if must_wait {
                        self.device.wait_for_fences(&[fence], true, u64::MAX).map_err(vk_error("vkWaitForFences"))?;
                        true
                    } else {
                        self.device.get_fence_status(fence).map_err(vk_error("vkGetFenceStatus"))?
                    }
                };
                if !done {
                    break;
                }
                tracker.in_flight.pop_front();
                tracker.completed = seq;
                // SAFETY: the fence has signalled and is referenced nowhere else.
                unsafe { self.device.destroy_fence(fence, None) };
            }
            let completed = tracker.completed;
            let (ready, waiting): (Vec<_>, Vec<_>) =
                std::mem::take(&mut tracker.garbage).into_iter().partition(|(seq, _)| *seq <= completed);
            tracker.garbage = waiting;
            freed.extend(ready.into_iter().map(|(_, g)| g));
        }
        for item in freed {
            self.destroy(item);
        }
        Ok(())
    }

    pub(crate) fn take_validation_messages(&self) -> Vec<String> {
        self.validation_log.as_ref().map(|l| std::mem::take(&mut *lock(&l.messages))).unwrap_or_default()
    }
}

impl Drop for Shared {
    fn drop(&mut self) {
        // SAFETY: every object made from this device holds an Arc of it, so
        // none is left; once srug's own submissions have finished (a host's
        // device: its fences; srug's own: the whole device idle) destroying
        // what remains is safe.
        unsafe {
            if self.owns_device {
                if let Err(e) = self.device.device_wait_idle() {
                    log::error!("vkDeviceWaitIdle failed while dropping the device: {e}");
                }
            } else {
                let fences: Vec<vk::Fence> = lock(&self.tracker).in_flight.iter().map(|f| f.1).collect();
                if !fences.is_empty() {
                    if let Err(e) = self.device.wait_for_fences(&fences, true, u64::MAX) {
                        log::error!("vkWaitForFences failed while dropping the device: {e}");
                    }
                }
            }
        }
        let tracker = std::mem::take(&mut *lock(&self.tracker));
        for (_, fence) in tracker.in_flight {
            // SAFETY: the device is idle.
            unsafe { self.device.destroy_fence(fence, None) };
        }
        for (_, item) in tracker.garbage {
            self.destroy(item);
        }
        self.drain_pool();
        // SAFETY: the allocator is dropped exactly once, before the device it uses.
        unsafe { ManuallyDrop::drop(&mut *lock(&self.allocator)) };
        // SAFETY: all child objects are gone; destruction order is device, messenger,
        // instance, and a host's device and instance are left to the host.
        unsafe {
            if self.owns_device {
                self.device.destroy_device(None);
            }
            if let Some((loader, messenger)) = self.debug.take() {
                loader.destroy_debug_utils_messenger(messenger, None);
            }
            if self.owns_device {
                self.instance.destroy_instance(None);
            }
        }
        if let Some(log) = &self.validation_log {
            let left = lock(&log.messages);
            for m in left.iter() {
                log::error!("unread validation message: {m}");
            }
        }
    }
}

pub(crate) unsafe extern "system" fn on_validation_message(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _types: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user: *mut c_void,
) -> vk::Bool32 {
    // SAFETY: the layer passes valid callback data for the duration of the call.
    let text = unsafe {
        data.as_ref()
            .filter(|d| !d.p_message.is_null())
            .map(|d| CStr::from_ptr(d.p_message).to_string_lossy().into_owned())
            .unwrap_or_default()
    };
    // Warnings and errors of every type: the layer's SPIR-V validator reports
    // shader problems as general messages.
    let counts = severity
        .intersects(vk::DebugUtilsMessageSeverityFlagsEXT::WARNING | vk::DebugUtilsMessageSeverityFlagsEXT::ERROR);
    if counts {
        log::error!("Vulkan validation: {text}");
        // SAFETY: `user` is the ValidationLog boxed in Shared, which outlives the messenger.
        if let Some(log) = unsafe { user.cast::<ValidationLog>().as_ref() } {
            lock(&log.messages).push(text);
        }
    } else {
        log::debug!("Vulkan: {text}");
    }
    vk::FALSE
}

#[cfg(test)]
mod tests {
    use super::pool_limit;

    #[test]
    fn the_pool_keeps_an_eighth_of_the_heap_within_its_bounds() {
        const GIB: u64 = 1 << 30;
        assert_eq!(pool_limit(0), 256 << 20, "no device-local heap");
        assert_eq!(pool_limit(GIB), 256 << 20);
        assert_eq!(pool_limit(24 * GIB), 3 * GIB, "lavapipe on this project's 24 GiB machine");
        assert_eq!(pool_limit(80 * GIB), 4 * GIB, "an H100");
    }
}
