//! `tonemap`: exposure + sRGB preview of the running mean (shaders/passes/tonemap.comp).

use std::sync::Arc;

use anyhow::Result;
use ash::vk;

use crate::shaders;
use crate::vk::pipeline::storage;
use crate::vk::{Binding, ComputePipeline, Context};

use super::FrameTargets;

pub struct TonemapPass {
    pipeline: ComputePipeline,
}

impl TonemapPass {
    pub const NAME: &'static str = "tonemap";
    pub const BINDINGS: &'static [Binding] = &[storage(0, "means"), storage(1, "preview")];

    pub fn new(ctx: &Arc<Context>, scene_layout: vk::DescriptorSetLayout, targets: &FrameTargets) -> Result<Self> {
        let pipeline =
            ComputePipeline::new(ctx, Self::NAME, shaders::PASSES_TONEMAP, scene_layout, Self::BINDINGS, 0, [64, 1, 1])?;
        pipeline.set1.write_buffer(0, &targets.mean)?;
        pipeline.set1.write_buffer(1, &targets.preview)?;
        Ok(Self { pipeline })
    }

    pub fn record(&self, cmd: vk::CommandBuffer, scene_set: vk::DescriptorSet, pixels: u32) {
        self.pipeline.dispatch_1d(cmd, scene_set, &[], pixels);
    }
}
