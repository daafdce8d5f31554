//! Host structs shared with shaders: device addresses as their own type, and
//! the check of a struct's field offsets against the block a shader declares.
//!
//! A uniform or push-constant struct implements [`GpuLayout`] through
//! [`gpu_layout!`](crate::gpu_layout), which lists its fields by the names
//! the GLSL block gives them; [`check_layout`] compares those offsets with the
//! ones reflected from the compiled SPIR-V, so a field added, moved or renamed
//! on one side only fails a test instead of reading the wrong bytes.

use bytemuck::{Pod, Zeroable};
use srug_spirv::{BlockInfo, KernelInfo};

/// A buffer's device address as a uniform or push-constant block holds it
/// (`uvec2` (low, high) in GLSL, 8 bytes). Only a
/// [`Recording`](crate::Recording) hands out a non-null one
/// ([`Recording::addr`](crate::Recording::addr)), and it keeps the buffer
/// borrowed until the recording is submitted, so the GPU never follows an
/// address into a freed buffer.
#[repr(transparent)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct DeviceAddress(u64);

impl DeviceAddress {
    /// No buffer: what a shader tests for an absent optional input.
    pub const NULL: Self = Self(0);

    pub(crate) fn new(address: u64) -> Self {
        Self(address)
    }

    pub(crate) fn offset(self, bytes: u64) -> Self {
        Self(self.0 + bytes)
    }

    /// Whether this is [`DeviceAddress::NULL`].
    pub fn is_null(self) -> bool {
        self.0 == 0
    }
}

/// A `#[repr(C)]` host struct mirrored by a GLSL uniform or push-constant block.
/// Implement it with [`gpu_layout!`](crate::gpu_layout).
pub trait GpuLayout: Pod {
    /// The GLSL block's type name (`Frame` for `uniform Frame { ... } frame;`).
    const BLOCK: &'static str;
    /// Every field the shader sees: its GLSL name and byte offset.
    const FIELDS: &'static [(&'static str, usize)];
}

/// Implements [`GpuLayout`] for a struct whose fields carry the GLSL block's
/// member names: `gpu_layout!(FrameUniform, "Frame", [rot0, rot1, size, means]);`.
/// A GLSL struct inside the block is listed member by member as
/// `camera.rot0, camera.rot1, ...` (a host field `camera` whose own fields
/// carry the GLSL struct's member names), as the reflection flattens it.
#[macro_export]
macro_rules! gpu_layout {
    ($ty:ty, $block:literal, [$($($field:ident).+),* $(,)?]) => {
        impl $crate::GpuLayout for $ty {
            const BLOCK: &'static str = $block;
            const FIELDS: &'static [(&'static str, usize)] =
                &[$((stringify!($($field).+), ::core::mem::offset_of!($ty, $($field).+))),*];
        }
    };
}

/// Checks `T` against one reflected block: the same member names in the same
/// order at the same offsets, and a struct as large as the block.
pub fn check_block<T: GpuLayout>(block: &BlockInfo) -> Result<(), String> {
    let glsl: Vec<(&str, usize)> = block.members.iter().map(|m| (m.name, m.offset as usize)).collect();
    if glsl != T::FIELDS {
        return Err(format!(
            "{} does not match GLSL block {}: host fields {:?}, GLSL members {:?}",
            std::any::type_name::<T>(),
            block.name,
            T::FIELDS,
            glsl
        ));
    }
    let end = block.members.iter().map(|m| (m.offset + m.size) as usize).max().unwrap_or(0);
    let size = std::mem::size_of::<T>();
    // The host struct may end in std140 padding up to the next 16 bytes, no further.
    if size < end || size > end.next_multiple_of(16) {
        return Err(format!("{} is {size} bytes, GLSL block {} ends at {end}", std::any::type_name::<T>(), block.name));
    }
    Ok(())
}

/// Checks `T` against every uniform and push-constant block named
/// [`GpuLayout::BLOCK`] in `kernels` (the kernels `T` serves: block names
/// such as `Push` repeat across unrelated kernels); returns how many it
/// checked (a block renamed in GLSL makes that 0, which callers should treat
/// as a failure).
pub fn check_layout<T: GpuLayout>(kernels: &[&KernelInfo]) -> Result<usize, String> {
    let mut checked = 0;
    for k in kernels {
        let blocks = k.bindings.iter().map(|b| &b.block).chain(std::iter::once(&k.push_constant_block));
        for block in blocks.filter(|b| b.name == T::BLOCK) {
            check_block::<T>(block).map_err(|e| format!("kernel {}: {e}", k.name))?;
            checked += 1;
        }
    }
    Ok(checked)
}
