//! srug's compute kernels as SPIR-V, with what the host needs to know about each.
//!
//! The build script compiles every `shaders/*.comp` with shaderc (GLSL 460,
//! Vulkan 1.2, SPIR-V 1.5) and reflects the result: workgroup size,
//! descriptor bindings, push-constant size and specialization constants. The
//! engine checks the bindings it declares in Rust against this table when it
//! builds a pipeline, so a shader and its host code cannot drift apart
//! silently; uniform and push-constant blocks carry their members' names and
//! offsets, against which host structs check their own layout. A GLSL error fails the build with the file and line.

/// What a descriptor binding holds, as the shader declares it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BindingKind {
    /// A `buffer` block; `read_only` when every member is `readonly`.
    StorageBuffer {
        /// The shader never writes through this binding.
        read_only: bool,
    },
    /// A `uniform` block.
    UniformBuffer,
    /// A `textureBuffer` (uniform texel buffer), read with `texelFetch`.
    UniformTexelBuffer,
}

/// One member of a uniform or push-constant block, as the shader lays it out.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemberInfo {
    /// The member's GLSL name, or "" when the compiler dropped it.
    pub name: &'static str,
    /// Byte offset in the block.
    pub offset: u32,
    /// Size in bytes.
    pub size: u32,
}

/// A uniform or push-constant block: its GLSL type name and members in order
/// (empty for storage buffers, texel buffers and kernels without push constants).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BlockInfo {
    /// The block's type name in GLSL (`Frame` in `uniform Frame { ... } frame;`).
    pub name: &'static str,
    /// Its members.
    pub members: &'static [MemberInfo],
}

/// One descriptor binding of a kernel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BindingInfo {
    /// Descriptor set index.
    pub set: u32,
    /// Binding index within the set.
    pub binding: u32,
    /// What the binding holds.
    pub kind: BindingKind,
    /// The block's instance name in GLSL, or "" when the compiler dropped it.
    pub name: &'static str,
    /// For a uniform block, its layout (members empty otherwise).
    pub block: BlockInfo,
}

/// One specialization constant of a kernel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SpecConstantInfo {
    /// The `constant_id`.
    pub id: u32,
    /// The constant's GLSL name, or "" when the compiler dropped it.
    pub name: &'static str,
    /// The default value's 32 bits.
    pub default_bits: u32,
}

/// A compiled kernel and its reflected interface.
#[derive(Clone, Copy, Debug)]
pub struct KernelInfo {
    /// File stem of the GLSL source, e.g. `"core_affine"`.
    pub name: &'static str,
    /// SPIR-V words.
    pub words: &'static [u32],
    /// `local_size_x/y/z` (the defaults where a dimension is specialized).
    pub workgroup_size: [u32; 3],
    /// Per dimension, the specialization constant that sets it
    /// (`local_size_x_id` etc.), `None` where it is fixed.
    pub workgroup_size_ids: [Option<u32>; 3],
    /// Descriptor bindings, sorted by (set, binding).
    pub bindings: &'static [BindingInfo],
    /// Size in bytes of the push-constant block, 0 when there is none.
    pub push_constant_size: u32,
    /// The push-constant block's layout (members empty when there is none).
    pub push_constant_block: BlockInfo,
    /// Specialization constants, sorted by id.
    pub spec_constants: &'static [SpecConstantInfo],
    /// Whether the kernel reads `gl_SubgroupID` or `gl_NumSubgroups`: where
    /// an invocation works depends on which subgroup holds it, which Vulkan
    /// pins down only for pipelines built with `REQUIRE_FULL_SUBGROUPS`
    /// (the kernel cache does so for these).
    pub full_subgroups: bool,
}

include!(concat!(env!("OUT_DIR"), "/kernels.rs"));
