//! Compute kernels: a pipeline from the SPIR-V table, its layouts, and the
//! specialization constants that pick a shader variant.
//!
//! The Rust side declares what it will bind and push ([`KernelDecl`]); creation
//! fails with [`Error::Kernel`] when that disagrees with the reflected SPIR-V,
//! so a shader edit that changes its interface cannot go unnoticed.

use std::sync::Arc;

use ash::vk;
use srug_spirv::{BindingKind, KernelInfo};

use crate::device::Device;
use crate::error::{vk_error, GpuError as Error, Result};
use crate::shared::{lock, Garbage, KernelKey, Shared};

/// A specialization constant's value (every GLSL scalar constant is 32 bits).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SpecValue {
    /// `uint`.
    U32(u32),
    /// `int`.
    I32(i32),
    /// `float`.
    F32(f32),
    /// `bool`.
    Bool(bool),
}

impl SpecValue {
    fn bits(self) -> u32 {
        match self {
            Self::U32(v) => v,
            Self::I32(v) => v as u32,
            Self::F32(v) => v.to_bits(),
            Self::Bool(v) => u32::from(v),
        }
    }
}

/// What the host code binds and pushes, checked against the SPIR-V.
#[derive(Clone, Copy, Debug)]
pub struct KernelDecl<'a> {
    /// Kinds of bindings 0..n of set 0, in order.
    pub bindings: &'a [BindingKind],
    /// `size_of` the Rust push-constant struct (0 for none).
    pub push_constant_size: usize,
    /// Specialization constants by `constant_id`.
    pub specialization: &'a [(u32, SpecValue)],
}

impl<'a> KernelDecl<'a> {
    /// A kernel that reads one uniform block at binding 0 and no push constants.
    pub const fn uniform(specialization: &'a [(u32, SpecValue)]) -> Self {
        Self { bindings: &[BindingKind::UniformBuffer], push_constant_size: 0, specialization }
    }

    /// A kernel that binds nothing and takes push constants `P` (buffers by address).
    pub const fn push<P>(specialization: &'a [(u32, SpecValue)]) -> Self {
        Self { bindings: &[], push_constant_size: std::mem::size_of::<P>(), specialization }
    }
}

/// A compute pipeline ready to dispatch. Dropping it is safe at any time.
pub struct Kernel {
    pub(crate) shared: Arc<Shared>,
    pub(crate) info: &'static KernelInfo,
    pub(crate) set_layout: Option<vk::DescriptorSetLayout>,
    pub(crate) layout: vk::PipelineLayout,
    pub(crate) pipeline: vk::Pipeline,
    pub(crate) push_constant_size: u32,
    pub(crate) descriptor_types: Vec<vk::DescriptorType>,
    /// The workgroup size after specialization.
    pub(crate) workgroup_size: [u32; 3],
}

impl std::fmt::Debug for Kernel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Kernel").field("name", &self.info.name).finish()
    }
}

/// Checks a declaration against reflected SPIR-V; returns the first disagreement.
pub fn check_decl(info: &KernelInfo, decl: &KernelDecl<'_>) -> Result<(), String> {
    if let Some(b) = info.bindings.iter().find(|b| b.set != 0) {
        return Err(format!("binding {} ({}) is in set {}; srug kernels use set 0 only", b.binding, b.name, b.set));
    }
    if decl.bindings.len() != info.bindings.len() {
        return Err(format!("Rust declares {} bindings, the SPIR-V has {}", decl.bindings.len(), info.bindings.len()));
    }
    for (i, (declared, actual)) in decl.bindings.iter().zip(info.bindings).enumerate() {
        if actual.binding != i as u32 {
            return Err(format!(
                "bindings must be 0..n without gaps; found binding {} at position {i}",
                actual.binding
            ));
        }
        if declared != &actual.kind {
            return Err(format!(
                "binding {i} ({}) is {:?} in the SPIR-V but {declared:?} in Rust",
                actual.name, actual.kind
            ));
        }
    }
    if decl.push_constant_size != info.push_constant_size as usize {
        return Err(format!(
            "push constants are {} bytes in Rust and {} in the SPIR-V",
            decl.push_constant_size, info.push_constant_size
        ));
    }
    for (id, _) in decl.specialization {
        if !info.spec_constants.iter().any(|s| s.id == *id) {
            return Err(format!("no specialization constant with constant_id {id}"));
        }
    }
    Ok(())
}

/// The workgroup size `decl` specializes `info` to (`local_size_*_id`
/// dimensions take their constant's value, the others the compiled size).
pub fn specialized_workgroup_size(info: &KernelInfo, decl: &KernelDecl<'_>) -> Result<[u32; 3], String> {
    let mut size = info.workgroup_size;
    for (dim, spec_id) in info.workgroup_size_ids.iter().enumerate() {
        let Some(spec_id) = spec_id else { continue };
        if let Some((_, value)) = decl.specialization.iter().find(|(id, _)| id == spec_id) {
            match value {
                SpecValue::U32(v) if *v > 0 => size[dim] = *v,
                other => return Err(format!("workgroup dimension {dim} (constant_id {spec_id}) set to {other:?}")),
            }
        }
    }
    Ok(size)
}

/// The stage flags a kernel is built with: `REQUIRE_FULL_SUBGROUPS` for
/// kernels that read their subgroup's index ([`KernelInfo::full_subgroups`]),
/// which needs the device's `computeFullSubgroups` and a workgroup width that
/// the subgroup size divides (without `ALLOW_VARYING_SUBGROUP_SIZE`, which
/// srug never sets, the subgroup size is the device's `subgroupSize`); an
/// error names what is missing.
pub fn full_subgroup_flags(
    info: &KernelInfo,
    workgroup_size: [u32; 3],
    device: &crate::DeviceInfo,
) -> Result<vk::PipelineShaderStageCreateFlags, String> {
    if !info.full_subgroups {
        return Ok(vk::PipelineShaderStageCreateFlags::empty());
    }
    if !device.full_subgroups {
        return Err("it places invocations by subgroup index, which needs computeFullSubgroups \
                    (VK_EXT_subgroup_size_control or Vulkan 1.3) enabled on the device"
            .into());
    }
    if device.subgroup_size == 0 || workgroup_size[0] % device.subgroup_size != 0 {
        return Err(format!(
            "full subgroups need a workgroup width that the subgroup size {} divides; it is {}",
            device.subgroup_size, workgroup_size[0]
        ));
    }
    Ok(vk::PipelineShaderStageCreateFlags::REQUIRE_FULL_SUBGROUPS)
}

impl Kernel {
    /// Builds the pipeline for `info` with the variant `decl.specialization` picks.
    pub fn new(device: &Device, info: &'static KernelInfo, decl: &KernelDecl<'_>) -> Result<Self> {
        check_decl(info, decl).map_err(|message| Error::Kernel { kernel: info.name, message })?;
        let workgroup_size =
            specialized_workgroup_size(info, decl).map_err(|message| Error::Kernel { kernel: info.name, message })?;
        let limits = device.info();
        let invocations: u64 = workgroup_size.iter().map(|&s| u64::from(s)).product();
        if workgroup_size.iter().zip(limits.max_workgroup_size).any(|(s, max)| *s > max)
            || invocations > u64::from(limits.max_workgroup_invocations)
        {
            return Err(Error::Kernel {
                kernel: info.name,
                message: format!(
                    "workgroup size {workgroup_size:?} exceeds this device's limits ({:?}, {} invocations)",
                    limits.max_workgroup_size, limits.max_workgroup_invocations
                ),
            });
        }
        let stage_flags = full_subgroup_flags(info, workgroup_size, limits)
            .map_err(|message| Error::Kernel { kernel: info.name, message })?;
        let shared = &device.shared;
        let d = &shared.device;
        let descriptor_types: Vec<vk::DescriptorType> = info
            .bindings
            .iter()
            .map(|b| match b.kind {
                BindingKind::StorageBuffer { .. } => vk::DescriptorType::STORAGE_BUFFER,
                BindingKind::UniformBuffer => vk::DescriptorType::UNIFORM_BUFFER,
                BindingKind::UniformTexelBuffer => vk::DescriptorType::UNIFORM_TEXEL_BUFFER,
            })
            .collect();
        let set_layout = if descriptor_types.is_empty() {
            None
        } else {
            let bindings: Vec<_> = descriptor_types
                .iter()
                .enumerate()
                .map(|(i, ty)| {
                    vk::DescriptorSetLayoutBinding::default()
                        .binding(i as u32)
                        .descriptor_type(*ty)
                        .descriptor_count(1)
                        .stage_flags(vk::ShaderStageFlags::COMPUTE)
                })
                .collect();
            let info = vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings);
            // SAFETY: valid create info.
            Some(
                unsafe { d.create_descriptor_set_layout(&info, None) }
                    .map_err(vk_error("vkCreateDescriptorSetLayout"))?,
            )
        };
        let mut kernel = Kernel {
            shared: shared.clone(),
            info,
            set_layout,
            layout: vk::PipelineLayout::null(),
            pipeline: vk::Pipeline::null(),
            push_constant_size: info.push_constant_size,
            descriptor_types,
            workgroup_size,
        };
        let set_layouts: Vec<_> = set_layout.into_iter().collect();
        let ranges = [vk::PushConstantRange {
            stage_flags: vk::ShaderStageFlags::COMPUTE,
            offset: 0,
            size: info.push_constant_size,
        }];
        let layout_info = vk::PipelineLayoutCreateInfo::default()
            .set_layouts(&set_layouts)
            .push_constant_ranges(if info.push_constant_size > 0 { &ranges } else { &[] });
        // SAFETY: valid create info; on error `kernel`'s Drop destroys what exists.
        kernel.layout =
            unsafe { d.create_pipeline_layout(&layout_info, None) }.map_err(vk_error("vkCreatePipelineLayout"))?;
        let module_info = vk::ShaderModuleCreateInfo::default().code(info.words);
        // SAFETY: the words are SPIR-V produced by shaderc at build time.
        let module = unsafe { d.create_shader_module(&module_info, None) }.map_err(vk_error("vkCreateShaderModule"))?;
        let entries: Vec<vk::SpecializationMapEntry> = decl
            .specialization
            .iter()
            .enumerate()
            .map(|(i, (id, _))| vk::SpecializationMapEntry { constant_id: *id, offset: 4 * i as u32, size: 4 })
            .collect();
        let data: Vec<u32> = decl.specialization.iter().map(|(_, v)| v.bits()).collect();
        let spec = vk::SpecializationInfo::default().map_entries(&entries).data(bytemuck::cast_slice(&data));
        let stage = vk::PipelineShaderStageCreateInfo::default()
            .flags(stage_flags)
            .stage(vk::ShaderStageFlags::COMPUTE)
            .module(module)
            .name(c"main")
            .specialization_info(&spec);
        let create = [vk::ComputePipelineCreateInfo::default().stage(stage).layout(kernel.layout)];
        log::trace!("kernel {} {:?}: building its pipeline", info.name, decl.specialization);
        let started = std::time::Instant::now();
        // SAFETY: module and layout are live; the module is destroyed right after.
        let result = unsafe { d.create_compute_pipelines(vk::PipelineCache::null(), &create, None) };
        log::debug!(
            "kernel {} {:?}: pipeline built in {:.1} ms",
            info.name,
            decl.specialization,
            started.elapsed().as_secs_f64() * 1e3
        );
        // SAFETY: pipelines keep no reference to the module after creation.
        unsafe { d.destroy_shader_module(module, None) };
        kernel.pipeline = result.map_err(|(_, e)| vk_error("vkCreateComputePipelines")(e))?[0];
        Ok(kernel)
    }

    /// The kernel's table entry.
    pub fn info(&self) -> &'static KernelInfo {
        self.info
    }

    /// The workgroup size this pipeline was specialized to.
    pub fn workgroup_size(&self) -> [u32; 3] {
        self.workgroup_size
    }
}

impl Device {
    /// The kernel for `info` with `decl`: built on first use, then shared by
    /// every caller on this device (and every clone of it) for as long as the
    /// device lives. This is the one kernel cache; stages ask it for the
    /// variant they need each time instead of keeping their own.
    pub fn kernel(&self, info: &'static KernelInfo, decl: &KernelDecl<'_>) -> Result<Arc<Kernel>> {
        let key = KernelKey {
            name: info.name,
            bindings: decl.bindings.to_vec(),
            push_constant_size: decl.push_constant_size,
            specialization: decl.specialization.iter().map(|(id, v)| (*id, v.bits())).collect(),
        };
        let cached = lock(&self.shared.kernel_cache).get(&key).cloned();
        if let Some(kernel) = cached.and_then(|k| k.downcast::<Kernel>().ok()) {
            return Ok(kernel);
        }
        // Built outside the lock: a pipeline compile can take seconds on a CPU driver.
        let kernel = Arc::new(Kernel::new(self, info, decl)?);
        let erased: Arc<dyn std::any::Any + Send + Sync> = kernel.clone();
        lock(&self.shared.kernel_cache).entry(key).or_insert(erased);
        Ok(kernel)
    }

    /// Kernels in the cache (built through [`Device::kernel`]).
    pub fn cached_kernels(&self) -> usize {
        lock(&self.shared.kernel_cache).len()
    }
}

impl Drop for Kernel {
    fn drop(&mut self) {
        self.shared.retire(Garbage::Pipeline {
            pipeline: self.pipeline,
            layout: self.layout,
            set_layout: self.set_layout,
        });
    }
}
