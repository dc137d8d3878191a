//! `restir_boiling`: RTXDI's boiling filter after temporal reuse (shaders/passes/restir_boiling.comp).
//! A pass of its own because it averages over 8×8 workgroups in shared memory, which a compute pass
//! has on both ways of tracing rays; it traces nothing. Only created with `--boiling-filter S > 0`
//! and temporal reuse. It sums each block with subgroup arithmetic (Vulkan 1.1; every device
//! measured has it, and one without is refused by name): 20 ms at 1280×720 on lavapipe against
//! 45 ms for a tree of seven workgroup barriers.

use std::sync::Arc;

use anyhow::Result;
use ash::vk;

use crate::shaders;
use crate::vk::pipeline::storage;
use crate::vk::{ComputePipeline, Context};

use super::desc::{push_constants, PassDesc};
use super::Reservoirs;

push_constants! {
    struct Push {
        /// `--boiling-filter` (> 0): drops a reservoir whose weight sum exceeds 10/S − 9 times its
        /// block's mean non-zero one.
        strength: f32,
    }
}

/// Set-1 variant v filters `reservoirs.buffer(v)` in place.
pub struct RestirBoilingPass { pipeline: ComputePipeline }

impl RestirBoilingPass {
    pub const NAME: &'static str = "restir_boiling";
    /// Fixed 8×8: the filter's blocks are its workgroups.
    pub const DESC: PassDesc = PassDesc::new(Self::NAME, shaders::PASSES_RESTIR_BOILING, [8, 8, 1])
        .with_push(Push::LAYOUT)
        .with_bindings(&[storage(0, "reservoirs")]);

    pub fn new(ctx: &Arc<Context>, scene_layout: vk::DescriptorSetLayout, reservoirs: &Reservoirs) -> Result<Self> {
        anyhow::ensure!(
            ctx.subgroup_arithmetic,
            "--boiling-filter: {} has no subgroup arithmetic in compute shaders (VkPhysicalDeviceSubgroupProperties), \
             which the filter's reduction over each 8×8 block uses; use --boiling-filter 0",
            ctx.report.name
        );
        let pipeline = Self::DESC.pipeline(ctx, scene_layout).ping_pong(reservoirs, 0, None).build()?;
        Ok(Self { pipeline })
    }

    /// Filters `reservoirs.buffer(current)`, the temporal pass's output.
    pub fn record(&self, cmd: vk::CommandBuffer, scene_set: vk::DescriptorSet, strength: f32, current: usize, w: u32, h: u32) {
        let push = Push { strength };
        self.pipeline.dispatch_2d_variant(cmd, current, scene_set, bytemuck::bytes_of(&push), w, h);
    }
}
