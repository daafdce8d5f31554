//! Buffers: named allocations through gpu-allocator, staged upload and readback.
//!
//! Invariants:
//! - every allocation is named and counted in [`MemoryUsage`](crate::MemoryUsage);
//! - a dropped buffer is destroyed only after every submission made before the
//!   drop has finished (see `Shared::retire`), so the GPU never reads freed memory;
//!   then, up to an eighth of the device's memory and within the most ever in use, it is kept
//!   (`BufferPool`) for the next buffer
//!   of its kind and of its size to a quarter less, whose contents are then
//!   undefined as fresh Vulkan memory's are (no code may rely on zeros);
//! - storage buffers carry a device address, so kernels can reach buffers larger
//!   than `maxStorageBufferRange` through `buffer_reference`.

use std::sync::atomic::Ordering;
use std::sync::Arc;

use ash::vk;
use bytemuck::Pod;
use gpu_allocator::vulkan::Allocation;
use gpu_allocator::MemoryLocation;

use crate::device::Device;
use crate::error::{vk_error, GpuError as Error, Result};
use crate::format::TexelFormat;
use crate::shared::{lock, Garbage, PooledKey, Shared};

/// Bytes moved per staging round trip; bounds host memory for huge buffers.
const STAGING_CHUNK: u64 = 64 << 20;

/// Where a buffer lives and what it is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MemoryKind {
    /// Device-local storage buffer, reached by kernels; filled by staging.
    Storage,
    /// Host-visible staging memory for uploads.
    Upload,
    /// Host-visible memory for readback.
    Readback,
}

/// A GPU buffer. Dropping it is safe at any time (destruction is deferred).
pub struct Buffer {
    pub(crate) shared: Arc<Shared>,
    pub(crate) raw: vk::Buffer,
    allocation: Option<Allocation>,
    size: u64,
    /// The Vulkan buffer's own size (≥ `size`; larger for a pooled buffer reused).
    vk_size: u64,
    name: String,
    address: u64,
    kind: MemoryKind,
    id: u64,
}

/// Source of [`Buffer::id`]s: unique for the life of the process.
static NEXT_BUFFER_ID: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);

impl std::fmt::Debug for Buffer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Buffer").field("name", &self.name).field("size", &self.size).finish()
    }
}

impl Buffer {
    /// Size in bytes as requested (the allocation may be larger).
    pub fn size(&self) -> u64 {
        self.size
    }

    /// The bytes commands and descriptors cover: the size asked for, at least
    /// 4 and a multiple of 4 (a reused pooled buffer may be larger).
    pub(crate) fn used_bytes(&self) -> u64 {
        self.size.max(4).next_multiple_of(4)
    }

    /// The name given at creation.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Device address for `buffer_reference` access (0 for non-storage
    /// buffers). Outside this crate an address comes only from
    /// [`Recording::addr`](crate::Recording::addr), which keeps the buffer alive.
    pub(crate) fn device_address(&self) -> u64 {
        self.address
    }

    /// A number no other buffer of this process has had: tells buffers apart
    /// (the scene a frame was rendered from) without exposing their addresses.
    pub fn id(&self) -> u64 {
        self.id
    }

    /// The memory kind.
    pub fn kind(&self) -> MemoryKind {
        self.kind
    }

    fn mapped(&mut self) -> Result<&mut [u8]> {
        let size = self.size as usize;
        let name = self.name.clone();
        self.allocation
            .as_mut()
            .and_then(|a| a.mapped_slice_mut())
            .map(|s| &mut s[..size])
            .ok_or_else(|| Error::invalid(format!("buffer {name}"), "is not host-visible"))
    }
}

impl Drop for Buffer {
    fn drop(&mut self) {
        if let Some(allocation) = self.allocation.take() {
            let key = PooledKey { usage: usage_of(self.kind), address: self.address, vk_size: self.vk_size };
            self.shared.retire(Garbage::Buffer(self.raw, allocation, key));
        }
    }
}

/// The usage flags of a buffer of `kind` (each kind has its own).
fn usage_of(kind: MemoryKind) -> vk::BufferUsageFlags {
    match kind {
        MemoryKind::Storage => {
            vk::BufferUsageFlags::STORAGE_BUFFER
                | vk::BufferUsageFlags::UNIFORM_BUFFER
                | vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER
                | vk::BufferUsageFlags::TRANSFER_SRC
                | vk::BufferUsageFlags::TRANSFER_DST
                | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS
        }
        MemoryKind::Upload => vk::BufferUsageFlags::TRANSFER_SRC,
        MemoryKind::Readback => vk::BufferUsageFlags::TRANSFER_DST,
    }
}

impl Device {
    /// Creates a buffer of `size` bytes (a zero size is allowed and allocates 4).
    pub fn create_buffer(&self, name: &str, size: u64, kind: MemoryKind) -> Result<Buffer> {
        let shared = &self.shared;
        let vk_size = size.max(4).next_multiple_of(4);
        let usage = usage_of(kind);
        let location = match kind {
            MemoryKind::Storage => MemoryLocation::GpuOnly,
            MemoryKind::Upload => MemoryLocation::CpuToGpu,
            MemoryKind::Readback => MemoryLocation::GpuToCpu,
        };
        // A freed buffer of this kind and about this size, if one is kept (`BufferPool`).
        let pooled = lock(&shared.pool).take(usage, vk_size);
        if let Some(p) = pooled {
            shared.count_allocated(p.allocation.size());
            return Ok(Buffer {
                shared: shared.clone(),
                raw: p.raw,
                allocation: Some(p.allocation),
                size,
                vk_size: p.key.vk_size,
                name: name.to_string(),
                address: p.key.address,
                kind,
                id: NEXT_BUFFER_ID.fetch_add(1, Ordering::Relaxed),
            });
        }
        let info = vk::BufferCreateInfo::default().size(vk_size).usage(usage).sharing_mode(vk::SharingMode::EXCLUSIVE);
        // SAFETY: valid create info on a live device.
        let raw =
            unsafe { shared.device.create_buffer(&info, None) }.map_err(|e| match vk_error("vkCreateBuffer")(e) {
                Error::OutOfMemory(m) => Error::OutOfMemory(format!("buffer {name} ({size} bytes): {m}")),
                other => other,
            })?;
        // SAFETY: `raw` was just created on this device.
        let requirements = unsafe { shared.device.get_buffer_memory_requirements(raw) };
        let d = &shared.device;
        let allocation = shared.allocate_bound(
            &format!("buffer {name} ({size} bytes)"),
            name,
            requirements,
            location,
            true,
            "vkBindBufferMemory",
            // SAFETY: memory and offset come from an allocation meeting the requirements.
            |memory, offset| unsafe { d.bind_buffer_memory(raw, memory, offset) },
            // SAFETY: unused buffer, created above.
            || unsafe { d.destroy_buffer(raw, None) },
        )?;
        let address = if kind == MemoryKind::Storage {
            // SAFETY: the buffer has SHADER_DEVICE_ADDRESS usage and bound memory.
            unsafe { shared.device.get_buffer_device_address(&vk::BufferDeviceAddressInfo::default().buffer(raw)) }
        } else {
            0
        };
        Ok(Buffer {
            shared: shared.clone(),
            raw,
            allocation: Some(allocation),
            size,
            vk_size,
            name: name.to_string(),
            address,
            kind,
            id: NEXT_BUFFER_ID.fetch_add(1, Ordering::Relaxed),
        })
    }

    /// Creates a storage buffer holding `data`.
    pub fn upload<T: Pod>(&self, name: &str, data: &[T]) -> Result<Buffer> {
        let bytes: &[u8] = bytemuck::cast_slice(data);
        let buffer = self.create_buffer(name, bytes.len() as u64, MemoryKind::Storage)?;
        self.write_buffer(&buffer, 0, data)?;
        Ok(buffer)
    }

    /// Creates a storage buffer of `count` elements of `T`, every 32-bit word set to `word`
    /// (a sentinel, so "never written" differs from "wrote 0").
    pub fn create_filled<T: Pod>(&self, name: &str, count: usize, word: u32) -> Result<Buffer> {
        let size = (count as u64).checked_mul(std::mem::size_of::<T>() as u64).ok_or_else(|| {
            Error::invalid(format!("buffer {name}"), format!("{count} elements overflow the address space"))
        })?;
        let buffer = self.create_buffer(name, size, MemoryKind::Storage)?;
        self.run(|rec| rec.fill(&buffer, word))?;
        Ok(buffer)
    }

    /// Copies `data` into `buffer` at `byte_offset`, through staging memory.
    pub fn write_buffer<T: Pod>(&self, buffer: &Buffer, byte_offset: u64, data: &[T]) -> Result<()> {
        let bytes: &[u8] = bytemuck::cast_slice(data);
        let end = byte_offset.checked_add(bytes.len() as u64);
        if end.is_none_or(|e| e > buffer.size) || byte_offset % 4 != 0 {
            return Err(Error::invalid(
                format!("buffer {} ({} bytes)", buffer.name, buffer.size),
                format!(
                    "a write of {} bytes at offset {byte_offset} is out of bounds or not 4-byte aligned",
                    bytes.len()
                ),
            ));
        }
        if bytes.is_empty() {
            return Ok(());
        }
        let chunk = STAGING_CHUNK.min(bytes.len() as u64);
        let mut staging =
            self.create_buffer(&format!("{} (upload staging)", buffer.name), chunk, MemoryKind::Upload)?;
        for (i, part) in bytes.chunks(chunk as usize).enumerate() {
            staging.mapped()?[..part.len()].copy_from_slice(part);
            let dst = byte_offset + i as u64 * chunk;
            self.run(|rec| rec.copy(&staging, 0, buffer, dst, part.len() as u64))?;
        }
        Ok(())
    }

    /// Reads `count` elements of `T` starting at element `first`.
    pub fn read_range<T: Pod>(&self, buffer: &Buffer, first: u64, count: u64) -> Result<Vec<T>> {
        let elem = std::mem::size_of::<T>() as u64;
        let (start, len) = (first * elem, count * elem);
        if start.checked_add(len).is_none_or(|end| end > buffer.size) || elem == 0 {
            return Err(Error::invalid(
                format!("buffer {}", buffer.name),
                format!("a read of {count} elements at {first} is out of bounds"),
            ));
        }
        let part = self.create_buffer(&format!("{} (range)", buffer.name), len, MemoryKind::Storage)?;
        self.run(|rec| rec.copy(buffer, start, &part, 0, len))?;
        self.read_buffer(&part)
    }

    /// Reads a host-visible ([`MemoryKind::Readback`]) buffer straight from
    /// its mapping: no staging copy and no submission, for small results a
    /// recording copied into it (whose submission has finished).
    pub fn read_mapped<T: Pod>(&self, buffer: &Buffer) -> Result<Vec<T>> {
        let count = whole_elements::<T>(buffer)?;
        let bytes = buffer
            .allocation
            .as_ref()
            .and_then(|a| a.mapped_slice())
            .map(|s| &s[..buffer.size as usize])
            .ok_or_else(|| Error::invalid(format!("buffer {}", buffer.name), "is not host-visible"))?;
        let mut out: Vec<T> = vec![T::zeroed(); count];
        bytemuck::cast_slice_mut::<T, u8>(&mut out).copy_from_slice(bytes);
        Ok(out)
    }

    /// Reads a whole buffer back as elements of `T`.
    pub fn read_buffer<T: Pod>(&self, buffer: &Buffer) -> Result<Vec<T>> {
        let mut out: Vec<T> = vec![T::zeroed(); whole_elements::<T>(buffer)?];
        self.read_buffer_into(buffer, &mut out)?;
        Ok(out)
    }

    /// Reads a whole buffer back into `out`, which must hold exactly its bytes
    /// (the staging copy is the only one: for callers that own the destination,
    /// such as a numpy array).
    pub fn read_buffer_into<T: Pod>(&self, buffer: &Buffer, out: &mut [T]) -> Result<()> {
        let dst: &mut [u8] = bytemuck::cast_slice_mut(out);
        if dst.len() as u64 != buffer.size {
            return Err(Error::invalid(
                format!("buffer {} ({} bytes)", buffer.name, buffer.size),
                format!("cannot be read into {} bytes", dst.len()),
            ));
        }
        if dst.is_empty() {
            return Ok(());
        }
        let chunk = STAGING_CHUNK.min(buffer.size);
        let mut staging =
            self.create_buffer(&format!("{} (readback staging)", buffer.name), chunk, MemoryKind::Readback)?;
        for (i, part) in dst.chunks_mut(chunk as usize).enumerate() {
            let src = i as u64 * chunk;
            self.run(|rec| rec.copy(buffer, src, &staging, 0, part.len() as u64))?;
            part.copy_from_slice(&staging.mapped()?[..part.len()]);
        }
        Ok(())
    }
}

/// How many `T` the buffer holds, or an error where its bytes are not a whole number of them.
fn whole_elements<T: Pod>(buffer: &Buffer) -> Result<usize> {
    let elem = std::mem::size_of::<T>() as u64;
    if elem == 0 || buffer.size % elem != 0 {
        return Err(Error::invalid(
            format!("buffer {}", buffer.name),
            format!("holds {} bytes, not a whole number of {elem}-byte elements", buffer.size),
        ));
    }
    Ok((buffer.size / elem) as usize)
}

/// A run of `elements` elements of `buffer` starting `offset` bytes in, bound
/// to a `textureBuffer` through a texel-buffer view that the recording makes
/// (and destroys once its submission has finished). The offset must be a
/// multiple of the device's `minTexelBufferOffsetAlignment`, and `elements`
/// at most `maxTexelBufferElements`.
#[derive(Clone, Copy, Debug)]
pub struct Texels<'a> {
    /// The buffer (a [`MemoryKind::Storage`] one).
    pub buffer: &'a Buffer,
    /// Byte offset of the first element.
    pub offset: u64,
    /// Elements in the view (0 binds a one-element view the shader must not read).
    pub elements: u64,
    /// Element format.
    pub format: TexelFormat,
}
