//! `accumulate`: compensated running mean (and mean squared deviation) of the per-frame samples;
//! counts non-finite samples (shaders/passes/accumulate.comp).

use std::sync::Arc;

use anyhow::Result;
use ash::vk;

use crate::shaders;
use crate::vk::pipeline::storage;
use crate::vk::{ComputePipeline, Context};

use super::desc::{push_constants, PassDesc};
use super::FrameTargets;

push_constants! {
    struct Push {
        /// 1: this is the first frame of a new accumulation.
        reset: u32,
    }
}

pub struct AccumulatePass { pipeline: ComputePipeline }

impl AccumulatePass {
    pub const NAME: &'static str = "accumulate";
    pub const DESC: PassDesc = PassDesc::new(Self::NAME, shaders::PASSES_ACCUMULATE, [64, 1, 1])
        .with_push(Push::LAYOUT)
        .with_bindings(&[
            storage(0, "samples"), storage(1, "running_means"), storage(2, "compensation"),
            storage(3, "deviations"), storage(4, "means"), storage(5, "nonfinite_samples"),
        ]);

    pub fn new(ctx: &Arc<Context>, scene_layout: vk::DescriptorSetLayout, targets: &FrameTargets) -> Result<Self> {
        let t = targets;
        let buffers =
            [(0, &t.samples), (1, &t.accum_running_mean), (2, &t.accum_compensation), (3, &t.accum_deviations), (4, &t.mean), (5, &t.stats)];
        Ok(Self { pipeline: Self::DESC.pipeline(ctx, scene_layout).buffers(&buffers).build()? })
    }

    /// `reset`: this is the first frame of a new accumulation.
    pub fn record(&self, cmd: vk::CommandBuffer, scene_set: vk::DescriptorSet, pixels: u32, reset: bool) {
        let push = Push { reset: u32::from(reset) };
        self.pipeline.dispatch_1d(cmd, scene_set, bytemuck::bytes_of(&push), pixels);
    }
}
