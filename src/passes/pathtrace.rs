//! `pathtrace`: the ground-truth path tracer (NEE + BSDF sampling with MIS, Russian roulette),
//! one path per pixel per frame from the G-buffer's primary hit (shaders/passes/pathtrace.comp).

use std::sync::Arc;

use anyhow::Result;
use ash::vk;

use crate::shaders;
use crate::vk::pipeline::{storage, texels};
use crate::vk::{ComputePipeline, Context};

use super::desc::PassDesc;
use super::FrameTargets;

pub struct PathtracePass { pipeline: ComputePipeline }

impl PathtracePass {
    pub const NAME: &'static str = "pathtrace";
    pub const DESC: PassDesc = PassDesc::new(Self::NAME, shaders::PASSES_PATHTRACE, [8, 8, 1])
        .with_raygen(shaders::PASSES_PATHTRACE_RAYGEN)
        .with_textured_raygen(shaders::PASSES_PATHTRACE_TEXTURED_RAYGEN)
        .with_workgroup_spec()
        .with_textured(shaders::PASSES_PATHTRACE_TEXTURED)
        .with_bindings(&[texels(0, "surfaces"), storage(1, "samples"), storage(2, "ray_count")]);

    /// `textured`: the scene set has textures bound (see `SceneGpu::textured`).
    pub fn new(ctx: &Arc<Context>, scene_layout: vk::DescriptorSetLayout, textured: bool, targets: &FrameTargets) -> Result<Self> {
        let buffers = [(0, &targets.surfaces), (1, &targets.samples), (2, &targets.ray_counter)];
        Ok(Self { pipeline: Self::DESC.pipeline(ctx, scene_layout).workgroup(targets.workgroup).textured(textured).buffers(&buffers).build()? })
    }

    pub fn record(&self, cmd: vk::CommandBuffer, scene_set: vk::DescriptorSet, width: u32, height: u32) {
        self.pipeline.dispatch_2d(cmd, scene_set, &[], width, height);
    }
}
