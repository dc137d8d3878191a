//! `pathtrace`: the ground-truth path tracer (NEE + BSDF sampling with MIS, Russian roulette),
//! one path per pixel per frame from the G-buffer's primary hit (shaders/passes/pathtrace.comp).

use std::sync::Arc;

use anyhow::Result;
use ash::vk;

use crate::shaders;
use crate::vk::pipeline::storage;
use crate::vk::{Binding, ComputePipeline, Context};

use super::FrameTargets;

pub struct PathtracePass {
    pipeline: ComputePipeline,
}

impl PathtracePass {
    pub const NAME: &'static str = "pathtrace";
    pub const BINDINGS: &'static [Binding] =
        &[storage(0, "surfaces"), storage(1, "samples"), storage(2, "ray_count")];

    /// `textured`: the scene set has textures bound (see `SceneGpu::textured`).
    pub fn new(
        ctx: &Arc<Context>,
        scene_layout: vk::DescriptorSetLayout,
        textured: bool,
        targets: &FrameTargets,
    ) -> Result<Self> {
        let spirv = if textured { shaders::PASSES_PATHTRACE_TEXTURED } else { shaders::PASSES_PATHTRACE };
        let pipeline = ComputePipeline::new(ctx, Self::NAME, spirv, scene_layout, Self::BINDINGS, 0, [8, 8, 1])?;
        pipeline.set1.write_buffer(0, &targets.surfaces)?;
        pipeline.set1.write_buffer(1, &targets.samples)?;
        pipeline.set1.write_buffer(2, &targets.ray_counter)?;
        Ok(Self { pipeline })
    }

    pub fn record(&self, cmd: vk::CommandBuffer, scene_set: vk::DescriptorSet, width: u32, height: u32) {
        self.pipeline.dispatch_2d(cmd, scene_set, &[], width, height);
    }
}
