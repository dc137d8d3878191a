//! `gbuffer`: primary rays -> one `GpuSurface` per pixel (shaders/passes/gbuffer.comp).

use std::sync::Arc;

use anyhow::Result;
use ash::vk;

use crate::shaders;
use crate::vk::pipeline::storage;
use crate::vk::{Binding, ComputePipeline, Context};

use super::FrameTargets;

pub struct GbufferPass {
    pipeline: ComputePipeline,
}

impl GbufferPass {
    pub const NAME: &'static str = "gbuffer";
    pub const BINDINGS: &'static [Binding] = &[storage(0, "surfaces")];

    /// `textured`: the scene set has textures bound (see `SceneGpu::textured`).
    pub fn new(
        ctx: &Arc<Context>,
        scene_layout: vk::DescriptorSetLayout,
        textured: bool,
        targets: &FrameTargets,
    ) -> Result<Self> {
        let spirv = if textured { shaders::PASSES_GBUFFER_TEXTURED } else { shaders::PASSES_GBUFFER };
        let pipeline = ComputePipeline::new(ctx, Self::NAME, spirv, scene_layout, Self::BINDINGS, 0, [8, 8, 1])?;
        pipeline.set1.write_buffer(0, &targets.surfaces)?;
        Ok(Self { pipeline })
    }

    pub fn record(&self, cmd: vk::CommandBuffer, scene_set: vk::DescriptorSet, width: u32, height: u32) {
        self.pipeline.dispatch_2d(cmd, scene_set, &[], width, height);
    }
}
