//! Compute pipelines with explicit bindings: set 0 is the scene (declared once, see
//! `crate::scene_gpu`), set 1 holds a pass's own resources, described by a binding table (a pass
//! declares it in its `PassDesc`, see `crate::passes::desc`). Writing a resource checks it against
//! that table.
//!
//! On a device that traces with ray-tracing pipelines ([`super::context::Tracing::Pipeline`]), a pass that traces
//! rays is a ray-tracing pipeline instead: its `raygen` SPIR-V variant, the miss and closest-hit
//! shaders of shaders/rt/, and a shader binding table; it is recorded with `vkCmdTraceRaysKHR`
//! over the same invocations a dispatch would run, with the same sets and push constants.

use std::io::Cursor;
use std::sync::Arc;

use anyhow::{bail, Context as _, Result};
use ash::vk;

use super::{Buffer, Context};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BindingKind {
    StorageBuffer,
    UniformBuffer,
    /// A buffer read as typed texels (`utextureBuffer` + `texelFetch`) through its `texel_view`.
    UniformTexelBuffer,
    /// A buffer written as typed texels (`uimageBuffer` + `imageStore`) through its `texel_view`.
    StorageTexelBuffer,
    AccelerationStructure,
}

impl BindingKind {
    fn vk(self) -> vk::DescriptorType {
        match self {
            Self::StorageBuffer => vk::DescriptorType::STORAGE_BUFFER,
            Self::UniformBuffer => vk::DescriptorType::UNIFORM_BUFFER,
            Self::UniformTexelBuffer => vk::DescriptorType::UNIFORM_TEXEL_BUFFER,
            Self::StorageTexelBuffer => vk::DescriptorType::STORAGE_TEXEL_BUFFER,
            Self::AccelerationStructure => vk::DescriptorType::ACCELERATION_STRUCTURE_KHR,
        }
    }
}

/// One row of a binding table: binding number, kind and the GLSL name it has in the shader.
#[derive(Clone, Copy, Debug)]
pub struct Binding {
    pub binding: u32,
    pub kind: BindingKind,
    pub name: &'static str,
}

pub const fn storage(binding: u32, name: &'static str) -> Binding {
    Binding { binding, kind: BindingKind::StorageBuffer, name }
}
pub const fn uniform(binding: u32, name: &'static str) -> Binding {
    Binding { binding, kind: BindingKind::UniformBuffer, name }
}
pub const fn texels(binding: u32, name: &'static str) -> Binding {
    Binding { binding, kind: BindingKind::UniformTexelBuffer, name }
}
pub const fn storage_texels(binding: u32, name: &'static str) -> Binding {
    Binding { binding, kind: BindingKind::StorageTexelBuffer, name }
}
pub const fn accel(binding: u32, name: &'static str) -> Binding {
    Binding { binding, kind: BindingKind::AccelerationStructure, name }
}

/// A descriptor set with its layout and pool, built from a binding table. It may hold several
/// *variants* of the set (same layout, e.g. ping-pong buffers swapped); `set` is variant 0.
pub struct DescriptorSet {
    ctx: Arc<Context>,
    pub layout: vk::DescriptorSetLayout,
    pool: vk::DescriptorPool,
    pub set: vk::DescriptorSet,
    pub variants: Vec<vk::DescriptorSet>,
    pub table: &'static [Binding],
    pub name: String,
}

impl DescriptorSet {
    pub fn new(ctx: &Arc<Context>, name: &str, table: &'static [Binding]) -> Result<Self> {
        Self::with_variants(ctx, name, table, 1)
    }

    /// `count` variants of the set, all with the layout of `table`.
    pub fn with_variants(ctx: &Arc<Context>, name: &str, table: &'static [Binding], count: u32) -> Result<Self> {
        anyhow::ensure!(count >= 1, "descriptor set '{name}' needs at least one variant");
        let bindings: Vec<vk::DescriptorSetLayoutBinding> = table
            .iter()
            .map(|b| {
                vk::DescriptorSetLayoutBinding::default()
                    .binding(b.binding)
                    .descriptor_type(b.kind.vk())
                    .descriptor_count(1)
                    .stage_flags(ctx.pass_stages())
            })
            .collect();
        let device = &ctx.device;
        // SAFETY: valid device; create infos reference locals.
        unsafe {
            let layout = device
                .create_descriptor_set_layout(&vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings), None)
                .with_context(|| format!("descriptor set layout '{name}'"))?;
            ctx.set_name(layout, name);
            let mut sizes: Vec<vk::DescriptorPoolSize> = Vec::new();
            for b in table {
                match sizes.iter_mut().find(|s| s.ty == b.kind.vk()) {
                    Some(s) => s.descriptor_count += count,
                    None => sizes.push(vk::DescriptorPoolSize { ty: b.kind.vk(), descriptor_count: count }),
                }
            }
            if sizes.is_empty() {
                sizes.push(vk::DescriptorPoolSize { ty: vk::DescriptorType::STORAGE_BUFFER, descriptor_count: 1 });
            }
            // On failure, what was created before is destroyed (no Self owns it yet).
            let pool = match device.create_descriptor_pool(&vk::DescriptorPoolCreateInfo::default().max_sets(count).pool_sizes(&sizes), None) {
                Ok(pool) => pool,
                Err(e) => {
                    device.destroy_descriptor_set_layout(layout, None);
                    return Err(e).with_context(|| format!("descriptor pool '{name}'"));
                }
            };
            ctx.set_name(pool, name);
            let layouts = vec![layout; count as usize];
            let variants = match device
                .allocate_descriptor_sets(&vk::DescriptorSetAllocateInfo::default().descriptor_pool(pool).set_layouts(&layouts))
            {
                Ok(variants) => variants,
                Err(e) => {
                    device.destroy_descriptor_pool(pool, None);
                    device.destroy_descriptor_set_layout(layout, None);
                    return Err(e).with_context(|| format!("descriptor set '{name}'"));
                }
            };
            for (i, set) in variants.iter().enumerate() {
                if count == 1 {
                    ctx.set_name(*set, name);
                } else {
                    ctx.set_name(*set, &format!("{name}.variant{i}"));
                }
            }
            Ok(Self { ctx: ctx.clone(), layout, pool, set: variants[0], variants, table, name: name.to_string() })
        }
    }

    fn row(&self, binding: u32, kind: BindingKind) -> Result<&Binding> {
        let Some(row) = self.table.iter().find(|b| b.binding == binding) else {
            bail!("set '{}' has no binding {binding}", self.name);
        };
        if row.kind != kind {
            bail!("set '{}' binding {binding} ('{}') is {:?}, not {kind:?}", self.name, row.name, row.kind);
        }
        Ok(row)
    }

    /// Points `binding` of every variant at a buffer; the kind must match the table.
    pub fn write_buffer(&self, binding: u32, buffer: &Buffer) -> Result<()> {
        for v in 0..self.variants.len() {
            self.write_buffer_in(v, binding, buffer)?;
        }
        Ok(())
    }

    /// Points storage-buffer `binding` of every variant at `range` bytes of `buffer` from `offset`
    /// (a multiple of the device's `minStorageBufferOffsetAlignment`).
    pub fn write_buffer_range(&self, binding: u32, buffer: &Buffer, offset: u64, range: u64) -> Result<()> {
        let kind = BindingKind::StorageBuffer;
        self.row(binding, kind)?;
        let limits = &self.ctx.properties.limits;
        anyhow::ensure!(
            offset.is_multiple_of(limits.min_storage_buffer_offset_alignment.max(1)) && range <= u64::from(limits.max_storage_buffer_range) && offset + range <= buffer.size,
            "binding {binding} of '{}': bytes {offset}..{} of buffer '{}' ({} bytes) do not make a storage-buffer range on this device (alignment {}, at most {} bytes)",
            self.name,
            offset + range,
            buffer.name,
            buffer.size,
            limits.min_storage_buffer_offset_alignment,
            limits.max_storage_buffer_range
        );
        let info = vk::DescriptorBufferInfo::default().buffer(buffer.raw).offset(offset).range(range);
        for v in 0..self.variants.len() {
            self.write_in(v, binding, buffer, info)?;
        }
        Ok(())
    }

    /// Points `binding` of variant `variant` at a buffer.
    pub fn write_buffer_in(&self, variant: usize, binding: u32, buffer: &Buffer) -> Result<()> {
        self.write_in(variant, binding, buffer, buffer.descriptor())
    }

    /// Points `binding` of variant `variant` at `info`'s part of `buffer` (a buffer binding), or at
    /// its texel view (a texel binding).
    fn write_in(&self, variant: usize, binding: u32, buffer: &Buffer, info: vk::DescriptorBufferInfo) -> Result<()> {
        let set = *self
            .variants
            .get(variant)
            .with_context(|| format!("set '{}' has no variant {variant}", self.name))?;
        let kind = self
            .table
            .iter()
            .find(|b| b.binding == binding)
            .map(|b| b.kind)
            .with_context(|| format!("set '{}' has no binding {binding}", self.name))?;
        anyhow::ensure!(kind != BindingKind::AccelerationStructure, "binding {binding} of '{}' takes an acceleration structure", self.name);
        let info = [info];
        let views = [buffer.texel_view.unwrap_or_default()];
        let write = vk::WriteDescriptorSet::default().dst_set(set).dst_binding(binding).descriptor_type(kind.vk());
        let write = if matches!(kind, BindingKind::UniformTexelBuffer | BindingKind::StorageTexelBuffer) {
            anyhow::ensure!(
                buffer.texel_view.is_some(),
                "binding {binding} of '{}' takes texels, and buffer '{}' has no texel view",
                self.name,
                buffer.name
            );
            write.texel_buffer_view(&views)
        } else {
            write.buffer_info(&info)
        };
        // SAFETY: the set and buffer are valid; no command buffer using the set is pending.
        unsafe { self.ctx.device.update_descriptor_sets(&[write], &[]) };
        Ok(())
    }

    /// Points `binding` of every variant at an acceleration structure.
    pub fn write_accel(&self, binding: u32, accel: vk::AccelerationStructureKHR) -> Result<()> {
        self.row(binding, BindingKind::AccelerationStructure)?;
        let structures = [accel];
        for set in &self.variants {
            let mut as_info = vk::WriteDescriptorSetAccelerationStructureKHR::default().acceleration_structures(&structures);
            let mut write = vk::WriteDescriptorSet::default()
                .dst_set(*set)
                .dst_binding(binding)
                .descriptor_type(vk::DescriptorType::ACCELERATION_STRUCTURE_KHR)
                .push_next(&mut as_info);
            write.descriptor_count = 1;
            // SAFETY: as above.
            unsafe { self.ctx.device.update_descriptor_sets(&[write], &[]) };
        }
        Ok(())
    }
}

impl Drop for DescriptorSet {
    fn drop(&mut self) {
        if self.ctx.is_hung() {
            return; // a submission that did not finish may still use it (Context::wait_fence)
        }
        // SAFETY: no pending work uses the set.
        unsafe {
            self.ctx.device.destroy_descriptor_pool(self.pool, None);
            self.ctx.device.destroy_descriptor_set_layout(self.layout, None);
        }
    }
}

/// A compute pipeline: set 0 = scene, set 1 = the pass's own table, plus push constants. Or, built
/// from a [`PassShader::RayGen`], a ray-tracing pipeline with the same interface.
pub struct ComputePipeline {
    ctx: Arc<Context>,
    pub name: String,
    pub pipeline: vk::Pipeline,
    pub layout: vk::PipelineLayout,
    /// Dropped in [`ComputePipeline`]'s `Drop`, under the same lock as the pipeline.
    pub set1: std::mem::ManuallyDrop<DescriptorSet>,
    pub push_size: u32,
    pub local_size: [u32; 3],
    /// Some: a ray-tracing pipeline, traced through this table instead of dispatched.
    sbt: Option<ShaderBindingTable>,
}

/// A ray-tracing pipeline's shader binding table: the ray-generation record, the two miss records
/// (shaders/rt/payload.glsl's RT_CLOSEST_MISS and RT_SHADOW_MISS) and the one hit group.
struct ShaderBindingTable {
    _buffer: Buffer,
    raygen: vk::StridedDeviceAddressRegionKHR,
    miss: vk::StridedDeviceAddressRegionKHR,
    hit: vk::StridedDeviceAddressRegionKHR,
}

fn align_up(x: u64, a: u64) -> u64 {
    x.div_ceil(a) * a
}

/// The shader a pass pipeline runs: a compute shader (`specialise`: its local size is
/// specialisable, `local_size_x_id = 0, local_size_y_id = 1`, and the pipeline's local size x and y
/// are passed as those constants), or a pass that traces compiled as a ray-generation shader (its
/// `raygen` SPIR-V variant), run by a ray-tracing pipeline with the hit and miss shaders of
/// shaders/rt/ on a context that traces with [`super::context::Tracing::Pipeline`]. `constants`:
/// further (constant_id, 32-bit value) specialisation constants of the pass's shader (ids from 2).
#[derive(Clone, Copy)]
pub enum PassShader<'a> {
    Compute { spirv: &'a [u8], specialise: bool, constants: &'a [(u32, u32)] },
    RayGen { spirv: &'a [u8], constants: &'a [(u32, u32)] },
}

/// Specialisation map entries and data for `constants` ((constant_id, 32-bit value) pairs).
fn specialisation(constants: &[(u32, u32)]) -> (Vec<vk::SpecializationMapEntry>, Vec<u8>) {
    let entries = constants
        .iter()
        .enumerate()
        .map(|(i, &(id, _))| vk::SpecializationMapEntry { constant_id: id, offset: 4 * i as u32, size: 4 })
        .collect();
    let data = constants.iter().flat_map(|&(_, v)| v.to_ne_bytes()).collect();
    (entries, data)
}

impl ComputePipeline {
    /// `spirv`: the module's bytes (from build.rs); `local_size`: the shader's workgroup size, used
    /// by [`ComputePipeline::dispatch_2d`] and friends.
    pub fn new(
        ctx: &Arc<Context>,
        name: &str,
        spirv: &[u8],
        scene_layout: vk::DescriptorSetLayout,
        table: &'static [Binding],
        push_size: u32,
        local_size: [u32; 3],
    ) -> Result<Self> {
        let shader = PassShader::Compute { spirv, specialise: false, constants: &[] };
        Self::with_variants(ctx, name, shader, scene_layout, table, push_size, local_size, 1)
    }

    /// A pass pipeline running `shader`, with `variants` set-1 variants (see
    /// [`DescriptorSet::with_variants`]). `local_size` is the compute shader's (or, for a
    /// ray-generation shader, the compute version's, whose invocations a launch reproduces).
    #[allow(clippy::too_many_arguments)]
    pub fn with_variants(
        ctx: &Arc<Context>,
        name: &str,
        shader: PassShader<'_>,
        scene_layout: vk::DescriptorSetLayout,
        table: &'static [Binding],
        push_size: u32,
        local_size: [u32; 3],
        variants: u32,
    ) -> Result<Self> {
        // Everything the pipeline is made of (set 1, modules, layout, pipeline, binding table) is
        // made under the lock that keeps NVIDIA's driver from deadlocking (Context's
        // DEVICE_LIFETIME); the driver's frames were not named, so all of it, not only the call.
        let _guard = super::context::pipeline_creation_guard();
        let (set1, layout, pipeline, sbt) = match shader {
            PassShader::Compute { spirv, specialise, constants } => {
                let sources = [(spirv, name.to_string())];
                let (set1, layout, pipeline) = create_pass_pipeline(ctx, name, scene_layout, table, push_size, variants, &sources, |layout, modules| {
                    compute_pipeline(ctx, name, layout, modules[0], specialise.then_some(local_size), constants)
                })?;
                (set1, layout, pipeline, None)
            }
            PassShader::RayGen { spirv: raygen, constants } => {
                let rt = ctx.ray_tracing.as_ref().with_context(|| {
                    format!("pass '{name}': a ray-tracing pipeline on a context that traces with {}", ctx.tracing.describe())
                })?;
                let sources = [
                    (raygen, name.to_string()),
                    (crate::shaders::RT_MISS, format!("{name}.miss")),
                    (crate::shaders::RT_SHADOW_MISS, format!("{name}.shadow_miss")),
                    (crate::shaders::RT_CLOSEST_HIT, format!("{name}.closest_hit")),
                ];
                let (set1, layout, pipeline) = create_pass_pipeline(ctx, name, scene_layout, table, push_size, variants, &sources, |layout, modules| {
                    ray_tracing_pipeline(ctx, rt, name, layout, modules, constants)
                })?;
                match shader_binding_table(ctx, name, pipeline, RT_GROUPS) {
                    Ok(sbt) => (set1, layout, pipeline, Some(sbt)),
                    Err(e) => {
                        // SAFETY: nothing uses the pipeline yet.
                        unsafe {
                            ctx.device.destroy_pipeline(pipeline, None);
                            ctx.device.destroy_pipeline_layout(layout, None);
                        }
                        return Err(e);
                    }
                }
            }
        };
        let set1 = std::mem::ManuallyDrop::new(set1);
        Ok(Self { ctx: ctx.clone(), name: name.to_string(), pipeline, layout, set1, push_size, local_size, sbt })
    }

    /// Binds the pipeline and both sets, pushes constants and dispatches `groups`.
    pub fn dispatch(&self, cmd: vk::CommandBuffer, scene_set: vk::DescriptorSet, push: &[u8], groups: [u32; 3]) {
        self.dispatch_variant(cmd, 0, scene_set, push, groups);
    }

    /// As [`ComputePipeline::dispatch`] with set-1 variant `variant`.
    pub fn dispatch_variant(
        &self,
        cmd: vk::CommandBuffer,
        variant: usize,
        scene_set: vk::DescriptorSet,
        push: &[u8],
        groups: [u32; 3],
    ) {
        let size = [0, 1, 2].map(|i| groups[i] * self.local_size[i]);
        self.launch(cmd, variant, scene_set, push, groups, size);
    }

    /// Binds the pipeline, set 0, set-1 variant `variant` and the push constants, then dispatches
    /// `groups` (a compute pipeline) or traces a launch of `size` invocations (a ray-tracing one).
    fn launch(&self, cmd: vk::CommandBuffer, variant: usize, scene_set: vk::DescriptorSet, push: &[u8], groups: [u32; 3], size: [u32; 3]) {
        let set1 = self.set1.variants[variant];
        debug_assert_eq!(push.len() as u32, self.push_size, "push constant size of '{}'", self.name);
        let d = &self.ctx.device;
        let bind_point = if self.sbt.is_some() { vk::PipelineBindPoint::RAY_TRACING_KHR } else { vk::PipelineBindPoint::COMPUTE };
        // SAFETY: cmd is recording; all objects are alive for the command buffer's lifetime.
        unsafe {
            d.cmd_bind_pipeline(cmd, bind_point, self.pipeline);
            d.cmd_bind_descriptor_sets(cmd, bind_point, self.layout, 0, &[scene_set, set1], &[]);
            if !push.is_empty() {
                d.cmd_push_constants(cmd, self.layout, self.ctx.pass_stages(), 0, push);
            }
            match (&self.sbt, &self.ctx.ray_tracing) {
                (Some(sbt), Some(rt)) => {
                    let callable = vk::StridedDeviceAddressRegionKHR::default();
                    rt.loader.cmd_trace_rays(cmd, &sbt.raygen, &sbt.miss, &sbt.hit, &callable, size[0], size[1], size[2]);
                }
                _ => d.cmd_dispatch(cmd, groups[0], groups[1], groups[2]),
            }
        }
    }

    /// Dispatches one invocation per pixel of a `width`×`height` image.
    pub fn dispatch_2d(&self, cmd: vk::CommandBuffer, scene_set: vk::DescriptorSet, push: &[u8], width: u32, height: u32) {
        self.dispatch_2d_variant(cmd, 0, scene_set, push, width, height);
    }

    /// [`ComputePipeline::dispatch_2d`] with set-1 variant `variant`.
    pub fn dispatch_2d_variant(
        &self,
        cmd: vk::CommandBuffer,
        variant: usize,
        scene_set: vk::DescriptorSet,
        push: &[u8],
        width: u32,
        height: u32,
    ) {
        let groups = [width.div_ceil(self.local_size[0]), height.div_ceil(self.local_size[1]), 1];
        // A launch has no workgroups to fill: exactly the image.
        self.launch(cmd, variant, scene_set, push, groups, [width, height, 1]);
    }

    /// Dispatches one invocation per item of a 1-D range of `count` items. The shader indexes
    /// items with `dispatch_index()` (shaders/lib/dispatch.glsl) and skips indices ≥ `count`.
    pub fn dispatch_1d(&self, cmd: vk::CommandBuffer, scene_set: vk::DescriptorSet, push: &[u8], count: u32) {
        let groups = count.div_ceil(self.local_size[0]).max(1);
        let max_x = self.ctx.properties.limits.max_compute_work_group_count[0];
        // A launch folds the same way, in rows of the same length (dispatch_index() in
        // shaders/lib/dispatch.glsl reads them alike).
        self.dispatch(cmd, scene_set, push, grid_1d(groups, max_x));
    }
}

/// What every pass pipeline is made of: set 1 (`variants` of `table`), a shader module per
/// (SPIR-V, debug name) of `sources`, and the pass layout (set 0 = `scene_layout`, set 1, `push_size`
/// bytes of push constants); `create` makes the pipeline from the layout and the modules. The
/// modules are destroyed once it has run, the layout too when it fails.
#[allow(clippy::too_many_arguments)]
fn create_pass_pipeline(
    ctx: &Arc<Context>,
    name: &str,
    scene_layout: vk::DescriptorSetLayout,
    table: &'static [Binding],
    push_size: u32,
    variants: u32,
    sources: &[(&[u8], String)],
    create: impl FnOnce(vk::PipelineLayout, &[vk::ShaderModule]) -> Result<vk::Pipeline>,
) -> Result<(DescriptorSet, vk::PipelineLayout, vk::Pipeline)> {
    let set1 = DescriptorSet::with_variants(ctx, &format!("{name}.set1"), table, variants)?;
    let device = &ctx.device;
    let mut modules = Vec::with_capacity(sources.len());
    // SAFETY: valid device; the SPIR-V was produced by glslang at build time; each module is
    // destroyed below, on every path.
    unsafe {
        let destroy_modules = |modules: &[vk::ShaderModule]| modules.iter().for_each(|m| device.destroy_shader_module(*m, None));
        for (spirv, module_name) in sources {
            match shader_module(ctx, module_name, spirv) {
                Ok(m) => modules.push(m),
                Err(e) => {
                    destroy_modules(&modules);
                    return Err(e);
                }
            }
        }
        let layout = match pipeline_layout(ctx, name, scene_layout, set1.layout, push_size) {
            Ok(layout) => layout,
            Err(e) => {
                destroy_modules(&modules);
                return Err(e);
            }
        };
        let pipeline = create(layout, &modules);
        destroy_modules(&modules);
        match pipeline {
            Ok(pipeline) => {
                ctx.set_name(pipeline, name);
                Ok((set1, layout, pipeline))
            }
            Err(e) => {
                device.destroy_pipeline_layout(layout, None);
                Err(e)
            }
        }
    }
}

/// A compute pipeline of `module` on `layout`; `local_size` Some: its x and y passed as
/// specialisation constants 0 and 1; `constants`: the shader's others.
fn compute_pipeline(
    ctx: &Context,
    name: &str,
    layout: vk::PipelineLayout,
    module: vk::ShaderModule,
    local_size: Option<[u32; 3]>,
    constants: &[(u32, u32)],
) -> Result<vk::Pipeline> {
    let all: Vec<(u32, u32)> = local_size.map(|l| [(0, l[0]), (1, l[1])]).into_iter().flatten().chain(constants.iter().copied()).collect();
    let (spec_entries, spec_data) = specialisation(&all);
    let spec = vk::SpecializationInfo::default().map_entries(&spec_entries).data(&spec_data);
    let stage = vk::PipelineShaderStageCreateInfo::default().stage(vk::ShaderStageFlags::COMPUTE).module(module).name(c"main");
    let stage = if all.is_empty() { stage } else { stage.specialization_info(&spec) };
    let info = [vk::ComputePipelineCreateInfo::default().stage(stage).layout(layout)];
    // SAFETY: valid device, module and layout (create_pass_pipeline's contract).
    match unsafe { ctx.device.create_compute_pipelines(ctx.pipeline_cache, &info, None) } {
        Ok(pipelines) => Ok(pipelines[0]),
        Err((_, e)) => Err(anyhow::anyhow!("compute pipeline '{name}': {e}")),
    }
}

/// The shader groups of a ray-tracing pass pipeline: ray generation, the two miss shaders, the hit
/// group (shader_binding_table lays their records out in this order).
const RT_GROUPS: u32 = 4;

/// A ray-tracing pipeline of `modules` (ray generation, miss, shadow miss, closest hit) on
/// `layout`: one general group per shader but the last, one triangle hit group with it;
/// `constants` specialise the ray-generation shader.
fn ray_tracing_pipeline(
    ctx: &Context,
    rt: &super::context::RayTracingPipelines,
    name: &str,
    layout: vk::PipelineLayout,
    modules: &[vk::ShaderModule],
    constants: &[(u32, u32)],
) -> Result<vk::Pipeline> {
    let (spec_entries, spec_data) = specialisation(constants);
    let spec = vk::SpecializationInfo::default().map_entries(&spec_entries).data(&spec_data);
    let kinds = [
        vk::ShaderStageFlags::RAYGEN_KHR,
        vk::ShaderStageFlags::MISS_KHR,
        vk::ShaderStageFlags::MISS_KHR,
        vk::ShaderStageFlags::CLOSEST_HIT_KHR,
    ];
    let stages: Vec<vk::PipelineShaderStageCreateInfo> = kinds
        .iter()
        .zip(modules)
        .map(|(stage, module)| vk::PipelineShaderStageCreateInfo::default().stage(*stage).module(*module).name(c"main"))
        .enumerate()
        .map(|(i, stage)| if i == 0 && !constants.is_empty() { stage.specialization_info(&spec) } else { stage })
        .collect();
    let general = |i: u32| {
        vk::RayTracingShaderGroupCreateInfoKHR::default()
            .ty(vk::RayTracingShaderGroupTypeKHR::GENERAL)
            .general_shader(i)
            .closest_hit_shader(vk::SHADER_UNUSED_KHR)
            .any_hit_shader(vk::SHADER_UNUSED_KHR)
            .intersection_shader(vk::SHADER_UNUSED_KHR)
    };
    let groups: [vk::RayTracingShaderGroupCreateInfoKHR; RT_GROUPS as usize] = [
        general(0),
        general(1),
        general(2),
        vk::RayTracingShaderGroupCreateInfoKHR::default()
            .ty(vk::RayTracingShaderGroupTypeKHR::TRIANGLES_HIT_GROUP)
            .general_shader(vk::SHADER_UNUSED_KHR)
            .closest_hit_shader(3)
            .any_hit_shader(vk::SHADER_UNUSED_KHR)
            .intersection_shader(vk::SHADER_UNUSED_KHR),
    ];
    // Recursion depth 1: only the ray-generation shader traces.
    let info = [vk::RayTracingPipelineCreateInfoKHR::default()
        .stages(&stages)
        .groups(&groups)
        .max_pipeline_ray_recursion_depth(1)
        .layout(layout)];
    // SAFETY: valid device, modules and layout (create_pass_pipeline's contract).
    match unsafe { rt.loader.create_ray_tracing_pipelines(vk::DeferredOperationKHR::null(), ctx.pipeline_cache, &info, None) } {
        Ok(pipelines) => Ok(pipelines[0]),
        Err((_, e)) => Err(anyhow::anyhow!("ray-tracing pipeline '{name}': {e}")),
    }
}

/// A shader module of build.rs's SPIR-V, named `name`.
///
/// # Safety
/// A valid context; the caller destroys the module.
unsafe fn shader_module(ctx: &Context, name: &str, spirv: &[u8]) -> Result<vk::ShaderModule> {
    let code = ash::util::read_spv(&mut Cursor::new(spirv)).with_context(|| format!("SPIR-V of '{name}'"))?;
    // SAFETY: valid device (caller's contract); the code is whole words.
    let module = unsafe { ctx.device.create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&code), None) }
        .with_context(|| format!("shader module '{name}'"))?;
    ctx.set_name(module, name);
    Ok(module)
}

/// The layout every pass has: set 0 (the scene), set 1 (its own) and `push_size` bytes of push
/// constants, for the stages the passes run in.
///
/// # Safety
/// A valid context and set layouts; the caller destroys the layout.
unsafe fn pipeline_layout(
    ctx: &Context,
    name: &str,
    scene_layout: vk::DescriptorSetLayout,
    set1_layout: vk::DescriptorSetLayout,
    push_size: u32,
) -> Result<vk::PipelineLayout> {
    let set_layouts = [scene_layout, set1_layout];
    let ranges = [vk::PushConstantRange::default().stage_flags(ctx.pass_stages()).offset(0).size(push_size.max(4))];
    let layout_info = vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts);
    let layout_info = if push_size > 0 { layout_info.push_constant_ranges(&ranges) } else { layout_info };
    // SAFETY: as above.
    let layout = unsafe { ctx.device.create_pipeline_layout(&layout_info, None) }.with_context(|| format!("pipeline layout '{name}'"))?;
    ctx.set_name(layout, name);
    Ok(layout)
}

/// The shader binding table of a ray-tracing pipeline with `groups` groups (ray generation, then
/// the miss shaders, then the hit group, as [`ray_tracing_pipeline`] makes them): each
/// region starts at a multiple of shaderGroupBaseAlignment, each record takes a multiple of
/// shaderGroupHandleAlignment. Host-visible: the handles are written once.
fn shader_binding_table(ctx: &Arc<Context>, name: &str, pipeline: vk::Pipeline, groups: u32) -> Result<ShaderBindingTable> {
    let rt = ctx.ray_tracing.as_ref().context("ray-tracing pipelines are not enabled")?;
    let handle = u64::from(rt.handle_size);
    let stride = align_up(handle, u64::from(rt.handle_alignment));
    let base = u64::from(rt.base_alignment);
    // SAFETY: the pipeline is a ray-tracing pipeline with `groups` groups.
    let handles = unsafe { rt.loader.get_ray_tracing_shader_group_handles(pipeline, 0, groups, (handle * u64::from(groups)) as usize) }
        .with_context(|| format!("shader group handles of '{name}'"))?;
    let miss_count = u64::from(groups) - 2;
    let miss_offset = align_up(stride, base);
    let hit_offset = align_up(miss_offset + miss_count * stride, base);
    let size = hit_offset + stride;
    // One base alignment more, so that the table can start at an aligned address in the buffer.
    let buffer = Buffer::new(
        ctx,
        &format!("{name}.sbt"),
        size + base,
        vk::BufferUsageFlags::SHADER_BINDING_TABLE_KHR | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
        gpu_allocator::MemoryLocation::CpuToGpu,
    )?;
    let start = align_up(buffer.address(), base);
    let skip = start - buffer.address();
    let record = |group: u64| &handles[(group * handle) as usize..((group + 1) * handle) as usize];
    buffer.write(skip as usize, record(0))?;
    for m in 0..miss_count {
        buffer.write((skip + miss_offset + m * stride) as usize, record(1 + m))?;
    }
    buffer.write((skip + hit_offset) as usize, record(u64::from(groups) - 1))?;
    let region = |offset: u64, count: u64| {
        vk::StridedDeviceAddressRegionKHR::default().device_address(start + offset).stride(stride).size(count * stride)
    };
    Ok(ShaderBindingTable { raygen: region(0, 1), miss: region(miss_offset, miss_count), hit: region(hit_offset, 1), _buffer: buffer })
}

impl Drop for ComputePipeline {
    fn drop(&mut self) {
        // All of it under the lock it was made under (see with_variants).
        let _guard = super::context::pipeline_creation_guard();
        if !self.ctx.is_hung() {
            // SAFETY: no pending work uses the pipeline (nor its binding table, dropped below).
            unsafe {
                self.ctx.device.destroy_pipeline(self.pipeline, None);
                self.ctx.device.destroy_pipeline_layout(self.layout, None);
            }
        } // else a submission that did not finish may still use them (Context::wait_fence)
        self.sbt = None;
        // SAFETY: dropped once, here; the field is not used after. (Its own Drop skips a hung device.)
        unsafe { std::mem::ManuallyDrop::drop(&mut self.set1) };
    }
}

/// `groups` workgroups of a 1-D dispatch as a grid whose x count is at most `max_x`
/// (maxComputeWorkGroupCount[0], 65,535 on lavapipe and Intel): rows along y of equal length,
/// the last one possibly running past `groups`. A u32 item count needs at most 1,025 rows, within
/// every device's y limit (also at least 65,535).
pub fn grid_1d(groups: u32, max_x: u32) -> [u32; 3] {
    if groups <= max_x {
        return [groups, 1, 1];
    }
    let rows = groups.div_ceil(max_x);
    [groups.div_ceil(rows), rows, 1]
}

/// First in every command buffer the renderer submits: the device writes of earlier submissions
/// (uploads, acceleration-structure builds, the photon pass, the previous frame) made visible to
/// this one. Waiting on a fence between the two does not do it: a fence's signal makes writes
/// available but visible to no later command (its second scope is empty), and a submission's
/// implicit ordering covers host writes only. lavapipe needs none of this; a GPU's caches may.
pub fn submission_start_barrier(ctx: &Context, cmd: vk::CommandBuffer) {
    let stages = ctx.pass_pipeline_stages() | vk::PipelineStageFlags::TRANSFER | vk::PipelineStageFlags::ACCELERATION_STRUCTURE_BUILD_KHR;
    let writes = vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::TRANSFER_WRITE | vk::AccessFlags::ACCELERATION_STRUCTURE_WRITE_KHR;
    // UNIFORM_READ apart: SHADER_READ does not cover it (a uniform buffer filled by a copy in an
    // earlier submission: `bench --rays`'s frame constants).
    let reads = vk::AccessFlags::SHADER_READ | vk::AccessFlags::UNIFORM_READ | vk::AccessFlags::TRANSFER_READ;
    memory_barrier(ctx, cmd, (stages, writes), (stages, reads | writes));
    // The acceleration structures' reads apart, in the stages that may read them: without the
    // rayQuery feature (ray-tracing pipelines) a barrier that gives ACCELERATION_STRUCTURE_READ
    // to the compute stage is invalid (VUID-vkCmdPipelineBarrier-dstAccessMask-06257; the
    // validation layer installed here does not check it).
    memory_barrier(ctx, cmd, (stages, writes), (ctx.acceleration_structure_read_stages(), vk::AccessFlags::ACCELERATION_STRUCTURE_READ_KHR));
}

/// Last in a command buffer whose results the host reads after its fence: the device writes made
/// visible to host reads (a fence wait alone makes them available, not visible).
pub fn host_read_barrier(ctx: &Context, cmd: vk::CommandBuffer) {
    let device_stages = ctx.pass_pipeline_stages() | vk::PipelineStageFlags::TRANSFER;
    let device_writes = vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::TRANSFER_WRITE;
    memory_barrier(ctx, cmd, (device_stages, device_writes), (vk::PipelineStageFlags::HOST, vk::AccessFlags::HOST_READ));
}

/// Transfer writes made available to the host, and nothing else: a breadcrumb's fill, which the
/// host reads while the frame may still be running ([`crate::vk::timer::GpuTimer::progress`]). Its
/// second scope is the host only, so later device work does not wait on it.
pub fn transfer_to_host_barrier(ctx: &Context, cmd: vk::CommandBuffer) {
    memory_barrier(ctx, cmd, (vk::PipelineStageFlags::TRANSFER, vk::AccessFlags::TRANSFER_WRITE), (vk::PipelineStageFlags::HOST, vk::AccessFlags::HOST_READ));
}

/// A full compute→compute (and →transfer) memory barrier between passes (transfer writes after
/// shader writes included: a counter cleared by vkCmdFillBuffer after a pass's atomics). With
/// ray-tracing pipelines, their shader stage too.
pub fn compute_barrier(ctx: &Context, cmd: vk::CommandBuffer) {
    let stages = ctx.pass_pipeline_stages() | vk::PipelineStageFlags::TRANSFER;
    let writes = vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::TRANSFER_WRITE;
    let reads = vk::AccessFlags::SHADER_READ | vk::AccessFlags::TRANSFER_READ;
    memory_barrier(ctx, cmd, (stages, writes), (stages, reads | writes));
}

/// One global memory barrier: `src` (stages, accesses) before `dst` (stages, accesses).
fn memory_barrier(
    ctx: &Context,
    cmd: vk::CommandBuffer,
    src: (vk::PipelineStageFlags, vk::AccessFlags),
    dst: (vk::PipelineStageFlags, vk::AccessFlags),
) {
    let barrier = [vk::MemoryBarrier::default().src_access_mask(src.1).dst_access_mask(dst.1)];
    // SAFETY: cmd is recording.
    unsafe { ctx.device.cmd_pipeline_barrier(cmd, src.0, dst.0, vk::DependencyFlags::empty(), &barrier, &[], &[]) };
}

#[cfg(test)]
mod tests {
    use super::grid_1d;

    #[test]
    fn grid_1d_covers_every_group_within_the_x_limit() {
        for &max_x in &[65_535u32, 1, 7, 1 << 31] {
            for &groups in &[1u32, 2, 65_535, 65_536, 65_625, 131_070, 131_071, 1_000_003, u32::MAX / 64 + 1] {
                let [x, y, z] = grid_1d(groups, max_x);
                assert!(x <= max_x && x >= 1 && z == 1, "{groups} groups, max {max_x}: {x}x{y}");
                let total = u64::from(x) * u64::from(y);
                // Every group is dispatched, and the overshoot is less than one row.
                assert!(total >= u64::from(groups) && total - u64::from(groups) < u64::from(x), "{groups} groups, max {max_x}: {x}x{y}");
                if max_x >= 65_535 {
                    assert!(y <= 65_535, "{groups} groups: {y} rows");
                }
            }
        }
    }
}
