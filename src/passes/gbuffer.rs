//! `gbuffer`: primary rays -> one `GpuSurface` per pixel (shaders/passes/gbuffer.comp).

use std::sync::Arc;

use anyhow::Result;
use ash::vk;

use crate::shaders;
use crate::vk::pipeline::storage_texels;
use crate::vk::{ComputePipeline, Context};

use super::desc::PassDesc;
use super::FrameTargets;

pub struct GbufferPass { pipeline: ComputePipeline }

impl GbufferPass {
    pub const NAME: &'static str = "gbuffer";
    pub const DESC: PassDesc = PassDesc::new(Self::NAME, shaders::PASSES_GBUFFER, [8, 8, 1])
        .with_workgroup_spec()
        .with_textured(shaders::PASSES_GBUFFER_TEXTURED)
        .with_bindings(&[storage_texels(0, "surfaces")]);

    /// `textured`: the scene set has textures bound (see `SceneGpu::textured`).
    pub fn new(ctx: &Arc<Context>, scene_layout: vk::DescriptorSetLayout, textured: bool, targets: &FrameTargets) -> Result<Self> {
        let pipeline = Self::DESC.pipeline(ctx, scene_layout).workgroup(targets.workgroup).textured(textured).buffers(&[(0, &targets.surfaces)]).build()?;
        Ok(Self { pipeline })
    }

    pub fn record(&self, cmd: vk::CommandBuffer, scene_set: vk::DescriptorSet, width: u32, height: u32) {
        self.pipeline.dispatch_2d(cmd, scene_set, &[], width, height);
    }
}
