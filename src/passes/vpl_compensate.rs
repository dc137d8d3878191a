//! `vpl_compensate`: adds to the frame's VPL estimate the energy Yuksel's clamped kernel removes
//! (Kollig & Keller 2004): one cosine-sampled ray from the pixel's surface, recursively, ended by
//! Russian roulette on the residual weight (shaders/passes/vpl_compensate.comp). Runs after
//! `vpl_shade` or `vpl_bruteforce` with `--compensate`.

use std::sync::Arc;

use anyhow::Result;
use ash::vk;

use crate::gpu_types::GpuVplParams;
use crate::shaders;
use crate::vk::pipeline::{storage, texels};
use crate::vk::{ComputePipeline, Context};

use super::desc::{push_constants, PassDesc};
use super::{FrameTargets, VplInputs};

push_constants! {
    struct Push {
        params: GpuVplParams,
        /// `COMPENSATE_*` bits: what the first ray's hit carries (the view's share of the image).
        first_hop: u32,
    }
}

pub struct VplCompensatePass { pipeline: ComputePipeline }

impl VplCompensatePass {
    pub const NAME: &'static str = "vpl_compensate";
    pub const DESC: PassDesc = PassDesc::new(Self::NAME, shaders::PASSES_VPL_COMPENSATE, [8, 8, 1])
        .with_raygen(shaders::PASSES_VPL_COMPENSATE_RAYGEN)
        .with_textured_raygen(shaders::PASSES_VPL_COMPENSATE_TEXTURED_RAYGEN)
        .with_workgroup_spec()
        .with_textured(shaders::PASSES_VPL_COMPENSATE_TEXTURED)
        .with_push(Push::LAYOUT)
        .with_bindings(&[texels(0, "surfaces"), texels(1, "vpls"), storage(2, "samples"), storage(3, "ray_count")]);

    /// `textured`: the scene set has textures bound (the hit's albedo is sampled).
    pub fn new(
        ctx: &Arc<Context>,
        scene_layout: vk::DescriptorSetLayout,
        textured: bool,
        targets: &FrameTargets,
        vpls: &VplInputs,
    ) -> Result<Self> {
        let buffers = [(0, &targets.surfaces), (1, vpls.vpls), (2, &targets.samples), (3, &targets.ray_counter)];
        Ok(Self { pipeline: Self::DESC.pipeline(ctx, scene_layout).workgroup(targets.workgroup).textured(textured).buffers(&buffers).build()? })
    }

    pub fn record(&self, cmd: vk::CommandBuffer, scene_set: vk::DescriptorSet, params: &GpuVplParams, first_hop: u32, w: u32, h: u32) {
        let push = Push { params: *params, first_hop };
        self.pipeline.dispatch_2d(cmd, scene_set, bytemuck::bytes_of(&push), w, h);
    }
}
