//! Each pass's interface to its shader, declared once: a [`PassDesc`] names the SPIR-V, the set-1
//! binding table, the push-constant layout (generated from the Rust `Push` struct by
//! [`push_constants!`]) and the workgroup size. `tests/layout.rs` checks every desc against the
//! SPIR-V of every variant; [`PipelineBuilder`] turns a desc into a [`ComputePipeline`] with its
//! buffers bound.

use std::sync::Arc;

use anyhow::{ensure, Context as _, Result};
use ash::vk;

use crate::vk::context::Tracing;
use crate::vk::pipeline::PassShader;
use crate::vk::{Binding, Buffer, ComputePipeline, Context};

use super::Reservoirs;

/// A push-constant block: its size and (member name, byte offset) of every top-level member.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PushLayout {
    pub size: usize,
    /// (name, byte offset, the member's GLSL type: [`PushMember::GLSL`]) per field.
    pub fields: &'static [(&'static str, usize, &'static str)],
}

/// A push-constant member's type as the shader declares it, so that `tests/layout.rs` compares
/// types too (a `u32` and an `f32` swapped at the same offset passed a check of names and offsets).
pub trait PushMember {
    const GLSL: &'static str;
}
impl PushMember for u32 {
    const GLSL: &'static str = "uint";
}
impl PushMember for i32 {
    const GLSL: &'static str = "int";
}
impl PushMember for f32 {
    const GLSL: &'static str = "float";
}
impl PushMember for [f32; 2] {
    const GLSL: &'static str = "vec2";
}
impl PushMember for [f32; 3] {
    const GLSL: &'static str = "vec3";
}
impl PushMember for [f32; 4] {
    const GLSL: &'static str = "vec4";
}
impl<T: crate::gpu_types::GpuStruct> PushMember for T {
    const GLSL: &'static str = T::GLSL_NAME;
}

impl PushLayout {
    /// A pass without push constants.
    pub const NONE: PushLayout = PushLayout { size: 0, fields: &[] };
}

/// Declares a pass's push-constant struct (`#[repr(C)]`, `Pod`) and its [`PushLayout`] as the
/// associated const `LAYOUT`, generated from the fields by `offset_of!`. A visibility before
/// `struct` applies to the struct, its fields and `LAYOUT` (a fused pass sharing a pass's block).
macro_rules! push_constants {
    ($(#[$m:meta])* $vis:vis struct $name:ident { $( $(#[$fm:meta])* $f:ident : $t:ty ),* $(,)? }) => {
        $(#[$m])*
        #[repr(C)]
        #[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
        $vis struct $name { $( $(#[$fm])* $vis $f: $t ),* }
        impl $name {
            $vis const LAYOUT: $crate::passes::desc::PushLayout = $crate::passes::desc::PushLayout {
                size: std::mem::size_of::<$name>(),
                fields: &[ $( (stringify!($f), std::mem::offset_of!($name, $f), <$t as $crate::passes::desc::PushMember>::GLSL) ),* ],
            };
        }
    };
}
pub(crate) use push_constants;

/// Everything a pass's Rust side and its shader must agree on.
#[derive(Clone, Copy)]
pub struct PassDesc {
    /// The pass's name: pipeline and set debug names, label and timer scope, summary keys.
    pub name: &'static str,
    /// SPIR-V of `shaders/passes/<name>.comp`.
    pub spirv: &'static [u8],
    /// SPIR-V of its `textured` variant (reads base-colour textures from set 0), where one exists.
    pub textured: Option<&'static [u8]>,
    /// A pass that traces rays: its `raygen` and `textured_raygen` variants (build.rs `RAYGEN`),
    /// the pass as a ray-generation shader, for a context that traces with ray-tracing pipelines.
    pub raygen: Option<&'static [u8]>,
    pub textured_raygen: Option<&'static [u8]>,
    /// SPIR-V of its `grid` variant (takes candidates from the ReGIR grid), and its ray-generation
    /// form, where they exist.
    pub grid: Option<&'static [u8]>,
    pub grid_raygen: Option<&'static [u8]>,
    /// Set 1, as the shader declares it.
    pub bindings: &'static [Binding],
    pub push: PushLayout,
    /// The shader's `local_size_x/y/z` (its default where `workgroup_spec`).
    pub local_size: [u32; 3],
    /// The shader's x and y local size are specialisation constants 0 and 1 (`local_size_x_id`,
    /// `local_size_y_id`), so the renderer can set them (`--workgroup`).
    pub workgroup_spec: bool,
    /// The shader's other specialisation constants, (constant_id, name) as its GLSL declares them
    /// (`layout(constant_id = N) const ... NAME`): settings fixed per pipeline, so the driver
    /// compiles only the code they select. A pipeline sets each with [`PipelineBuilder::constant`].
    pub constants: &'static [(u32, &'static str)],
}

impl PassDesc {
    /// A pass without set-1 bindings, push constants or a textured variant; the `with_*` methods
    /// add them.
    pub const fn new(name: &'static str, spirv: &'static [u8], local_size: [u32; 3]) -> Self {
        Self {
            name,
            spirv,
            textured: None,
            raygen: None,
            textured_raygen: None,
            grid: None,
            grid_raygen: None,
            bindings: &[],
            push: PushLayout::NONE,
            local_size,
            workgroup_spec: false,
            constants: &[],
        }
    }

    /// The shader's specialisation constants beyond the workgroup's.
    pub const fn with_constants(self, constants: &'static [(u32, &'static str)]) -> Self {
        Self { constants, ..self }
    }

    /// The shader's x and y local size are specialisation constants 0 and 1.
    pub const fn with_workgroup_spec(self) -> Self {
        Self { workgroup_spec: true, ..self }
    }

    pub const fn with_textured(self, spirv: &'static [u8]) -> Self {
        Self { textured: Some(spirv), ..self }
    }

    /// The pass traces rays: its ray-generation variant.
    pub const fn with_raygen(self, spirv: &'static [u8]) -> Self {
        Self { raygen: Some(spirv), ..self }
    }

    pub const fn with_textured_raygen(self, spirv: &'static [u8]) -> Self {
        Self { textured_raygen: Some(spirv), ..self }
    }

    /// The `grid` variant and its ray-generation form.
    pub const fn with_grid(self, spirv: &'static [u8], raygen: &'static [u8]) -> Self {
        Self { grid: Some(spirv), grid_raygen: Some(raygen), ..self }
    }

    pub const fn with_bindings(self, bindings: &'static [Binding]) -> Self {
        Self { bindings, ..self }
    }

    pub const fn with_push(self, push: PushLayout) -> Self {
        Self { push, ..self }
    }

    /// The local size a pipeline built with `.workgroup(workgroup)` runs: `workgroup` for a
    /// specialisable shader, the shader's own otherwise.
    pub fn local_size_with(&self, workgroup: [u32; 2]) -> [u32; 3] {
        if self.workgroup_spec {
            [workgroup[0], workgroup[1], self.local_size[2]]
        } else {
            self.local_size
        }
    }

    /// (variant name, SPIR-V) of every compiled variant: `default`, then `textured`, `raygen`,
    /// `textured_raygen`, `grid` and `grid_raygen` where they exist.
    pub fn spirv_variants(&self) -> Vec<(&'static str, &'static [u8])> {
        let mut out = vec![("default", self.spirv)];
        out.extend(self.textured.map(|spirv| ("textured", spirv)));
        out.extend(self.raygen.map(|spirv| ("raygen", spirv)));
        out.extend(self.textured_raygen.map(|spirv| ("textured_raygen", spirv)));
        out.extend(self.grid.map(|spirv| ("grid", spirv)));
        out.extend(self.grid_raygen.map(|spirv| ("grid_raygen", spirv)));
        out
    }

    /// Starts building the pass's pipeline on `scene_layout` (set 0).
    pub fn pipeline<'a>(&'a self, ctx: &'a Arc<Context>, scene_layout: vk::DescriptorSetLayout) -> PipelineBuilder<'a> {
        PipelineBuilder { desc: self, ctx, scene_layout, textured: false, grid: false, constants: Vec::new(), unknown_constants: Vec::new(), workgroup: None, shared: Vec::new(), per_variant: Vec::new(), ranges: Vec::new() }
    }
}

/// A pass's pipeline in the making: which SPIR-V variant, and the buffer behind every binding of
/// every set-1 variant. [`PipelineBuilder::build`] refuses a binding left unbound or bound twice.
pub struct PipelineBuilder<'a> {
    desc: &'a PassDesc,
    ctx: &'a Arc<Context>,
    scene_layout: vk::DescriptorSetLayout,
    textured: bool,
    grid: bool,
    /// (constant_id, value) of the desc's specialisation constants.
    constants: Vec<(u32, u32)>,
    /// Names given to [`PipelineBuilder::constant`] that the desc does not list.
    unknown_constants: Vec<String>,
    workgroup: Option<[u32; 2]>,
    shared: Vec<(u32, &'a Buffer)>,
    /// Empty: one set-1 variant.
    per_variant: Vec<Vec<(u32, &'a Buffer)>>,
    /// (binding, buffer, byte offset, byte range): storage bindings of part of a buffer.
    ranges: Vec<(u32, &'a Buffer, u64, u64)>,
}

impl<'a> PipelineBuilder<'a> {
    /// Use the `textured` SPIR-V when `textured` (the scene set has textures bound).
    pub fn textured(mut self, textured: bool) -> Self {
        self.textured = textured;
        self
    }

    /// Sets the specialisation constant `name` (one of the desc's `constants`) to `value`.
    pub fn constant(mut self, name: &str, value: u32) -> Self {
        match self.desc.constants.iter().find(|c| c.1 == name) {
            Some(&(id, _)) => self.constants.push((id, value)),
            None => self.unknown_constants.push(name.to_string()),
        }
        self
    }

    /// Use the `grid` SPIR-V when `grid` (the pass takes candidates from the ReGIR grid).
    pub fn grid(mut self, grid: bool) -> Self {
        self.grid = grid;
        self
    }

    /// The workgroup's x and y (a pass whose desc has `workgroup_spec`; `build` refuses others
    /// unless the size is the shader's own).
    pub fn workgroup(mut self, size: [u32; 2]) -> Self {
        self.workgroup = Some(size);
        self
    }

    /// (binding, buffer) pairs bound in every set-1 variant.
    pub fn buffers(mut self, buffers: &[(u32, &'a Buffer)]) -> Self {
        self.shared.extend_from_slice(buffers);
        self
    }

    /// (binding, buffer, byte offset, byte range) storage bindings of part of a buffer, in every
    /// set-1 variant.
    pub fn buffer_ranges(mut self, ranges: &[(u32, &'a Buffer, u64, u64)]) -> Self {
        self.ranges.extend_from_slice(ranges);
        self
    }

    /// `count` set-1 variants (same layout); `variant(v)` lists the buffers particular to variant v.
    pub fn variants<I>(mut self, count: usize, variant: impl Fn(usize) -> I) -> Self
    where
        I: IntoIterator<Item = (u32, &'a Buffer)>,
    {
        self.per_variant = (0..count).map(|v| variant(v).into_iter().collect()).collect();
        self
    }

    /// Two set-1 variants over the reservoir buffers: in variant v, binding `current` is
    /// `reservoirs.buffer(v)` and binding `other` (if any) is the other buffer.
    pub fn ping_pong(self, reservoirs: &'a Reservoirs, current: u32, other: Option<u32>) -> Self {
        self.variants(2, |v| [(current, reservoirs.buffer(v))].into_iter().chain(other.map(|b| (b, reservoirs.buffer(1 - v)))))
    }

    /// Creates the pipeline (named after the pass) and writes every buffer into its set 1.
    pub fn build(self) -> Result<ComputePipeline> {
        let d = self.desc;
        let variants = self.per_variant.len().max(1);
        for v in 0..variants {
            let own = self.per_variant.get(v).map(Vec::as_slice).unwrap_or_default();
            for row in d.bindings {
                let times = self.shared.iter().chain(own).filter(|(b, _)| *b == row.binding).count()
                    + self.ranges.iter().filter(|r| r.0 == row.binding).count();
                ensure!(times == 1, "pass '{}': binding {} ('{}') of variant {v} is bound {times} times", d.name, row.binding, row.name);
            }
        }
        ensure!(!(self.textured && self.grid), "pass '{}' has no variant both textured and with the grid", d.name);
        // The variant asked for: textured, grid, or the default.
        let variant = |textured: Option<&'static [u8]>, grid: Option<&'static [u8]>, plain: &'static [u8]| match (self.textured, self.grid) {
            (true, _) => textured.with_context(|| format!("pass '{}' has no textured variant", d.name)),
            (_, true) => grid.with_context(|| format!("pass '{}' has no grid variant", d.name)),
            _ => Ok(plain),
        };
        ensure!(
            self.unknown_constants.is_empty(),
            "pass '{}' declares no specialisation constant {:?} (it has {:?})",
            d.name,
            self.unknown_constants,
            d.constants
        );
        for &(id, name) in d.constants {
            let times = self.constants.iter().filter(|c| c.0 == id).count();
            ensure!(times == 1, "pass '{}': specialisation constant {id} ('{name}') is set {times} times", d.name);
        }
        let push_size = u32::try_from(d.push.size).context("push-constant size")?;
        let workgroup = self.workgroup.unwrap_or([d.local_size[0], d.local_size[1]]);
        let local_size = d.local_size_with(workgroup);
        ensure!(local_size[..2] == workgroup, "pass '{}' has a fixed {:?} workgroup, not {workgroup:?}", d.name, d.local_size);
        let shader = match (self.ctx.tracing, d.raygen) {
            (Tracing::Pipeline, Some(raygen)) => {
                PassShader::RayGen { spirv: variant(d.textured_raygen, d.grid_raygen, raygen)?, constants: &self.constants }
            }
            _ => PassShader::Compute { spirv: variant(d.textured, d.grid, d.spirv)?, specialise: d.workgroup_spec, constants: &self.constants },
        };
        let pipeline =
            ComputePipeline::with_variants(self.ctx, d.name, shader, self.scene_layout, d.bindings, push_size, local_size, variants as u32)?;
        for &(binding, buffer) in &self.shared {
            pipeline.set1.write_buffer(binding, buffer)?;
        }
        for &(binding, buffer, offset, range) in &self.ranges {
            pipeline.set1.write_buffer_range(binding, buffer, offset, range)?;
        }
        for (v, own) in self.per_variant.iter().enumerate() {
            for &(binding, buffer) in own {
                pipeline.set1.write_buffer_in(v, binding, buffer)?;
            }
        }
        Ok(pipeline)
    }
}
