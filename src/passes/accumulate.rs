//! `accumulate`: compensated running mean (and sum of squares) of the per-frame samples; counts
//! non-finite samples (shaders/passes/accumulate.comp).

use std::sync::Arc;

use anyhow::Result;
use ash::vk;

use crate::shaders;
use crate::vk::pipeline::storage;
use crate::vk::{Binding, ComputePipeline, Context};

use super::FrameTargets;

pub struct AccumulatePass {
    pipeline: ComputePipeline,
}

impl AccumulatePass {
    pub const NAME: &'static str = "accumulate";
    pub const BINDINGS: &'static [Binding] = &[
        storage(0, "samples"),
        storage(1, "sums"),
        storage(2, "compensation"),
        storage(3, "squares"),
        storage(4, "means"),
        storage(5, "stats"),
    ];

    pub fn new(ctx: &Arc<Context>, scene_layout: vk::DescriptorSetLayout, targets: &FrameTargets) -> Result<Self> {
        let pipeline =
            ComputePipeline::new(ctx, Self::NAME, shaders::PASSES_ACCUMULATE, scene_layout, Self::BINDINGS, 4, [64, 1, 1])?;
        let s = &pipeline.set1;
        s.write_buffer(0, &targets.samples)?;
        s.write_buffer(1, &targets.accum_sum)?;
        s.write_buffer(2, &targets.accum_compensation)?;
        s.write_buffer(3, &targets.accum_squares)?;
        s.write_buffer(4, &targets.mean)?;
        s.write_buffer(5, &targets.stats)?;
        Ok(Self { pipeline })
    }

    /// `reset`: this is the first frame of a new accumulation.
    pub fn record(&self, cmd: vk::CommandBuffer, scene_set: vk::DescriptorSet, pixels: u32, reset: bool) {
        let push = u32::from(reset).to_le_bytes();
        self.pipeline.dispatch_1d(cmd, scene_set, &push, pixels);
    }
}
