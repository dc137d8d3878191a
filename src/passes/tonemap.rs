//! `tonemap`: exposure + sRGB preview of the running mean (shaders/passes/tonemap.comp).

use std::sync::Arc;

use anyhow::Result;
use ash::vk;

use crate::shaders;
use crate::vk::pipeline::storage;
use crate::vk::{ComputePipeline, Context};

use super::desc::PassDesc;
use super::FrameTargets;

pub struct TonemapPass { pipeline: ComputePipeline }

impl TonemapPass {
    pub const NAME: &'static str = "tonemap";
    pub const DESC: PassDesc = PassDesc::new(Self::NAME, shaders::PASSES_TONEMAP, [64, 1, 1])
        .with_bindings(&[storage(0, "means"), storage(1, "preview")]);

    pub fn new(ctx: &Arc<Context>, scene_layout: vk::DescriptorSetLayout, targets: &FrameTargets) -> Result<Self> {
        let pipeline = Self::DESC.pipeline(ctx, scene_layout).buffers(&[(0, &targets.mean), (1, &targets.preview)]).build()?;
        Ok(Self { pipeline })
    }

    pub fn record(&self, cmd: vk::CommandBuffer, scene_set: vk::DescriptorSet, pixels: u32) {
        self.pipeline.dispatch_1d(cmd, scene_set, &[], pixels);
    }
}
