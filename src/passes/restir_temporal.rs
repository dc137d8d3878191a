//! `restir_temporal`: merges the canonical reservoir with the previous frame's final one
//! (shaders/passes/restir_temporal.comp).

use std::sync::Arc;

use anyhow::Result;
use ash::vk;

use crate::gpu_types::GpuVplParams;
use crate::shaders;
use crate::vk::pipeline::storage;
use crate::vk::{Buffer, ComputePipeline, Context};

use super::desc::{push_constants, PassDesc};
use super::{FrameTargets, Reservoirs, VplInputs};

push_constants! {
    struct Push {
        params: GpuVplParams,
        mcap: f32,
    }
}

/// Set-1 variant v: current = `reservoirs.buffer(v)`, history = the other one.
pub struct RestirTemporalPass { pipeline: ComputePipeline }

impl RestirTemporalPass {
    pub const NAME: &'static str = "restir_temporal";
    pub const DESC: PassDesc = PassDesc::new(Self::NAME, shaders::PASSES_RESTIR_TEMPORAL, [8, 8, 1])
        .with_push(Push::LAYOUT)
        .with_bindings(&[
            storage(0, "surfaces"), storage(1, "prev_surfaces"), storage(2, "vpls"),
            storage(3, "reservoirs"), storage(4, "history"), storage(5, "ray_count"),
        ]);

    /// `prev_surfaces`: last frame's G-buffer (the current one when the pixels do not move).
    pub fn new(
        ctx: &Arc<Context>,
        scene_layout: vk::DescriptorSetLayout,
        targets: &FrameTargets,
        prev_surfaces: &Buffer,
        vpls: &VplInputs,
        reservoirs: &Reservoirs,
    ) -> Result<Self> {
        let pipeline = Self::DESC
            .pipeline(ctx, scene_layout)
            .buffers(&[(0, &targets.surfaces), (1, prev_surfaces), (2, vpls.vpls), (5, &targets.ray_counter)])
            .ping_pong(reservoirs, 3, Some(4))
            .build()?;
        Ok(Self { pipeline })
    }

    #[allow(clippy::too_many_arguments)]
    pub fn record(
        &self,
        cmd: vk::CommandBuffer,
        scene_set: vk::DescriptorSet,
        params: &GpuVplParams,
        mcap: f32,
        current: usize,
        w: u32,
        h: u32,
    ) {
        let push = Push { params: *params, mcap };
        self.pipeline.dispatch_2d_variant(cmd, current, scene_set, bytemuck::bytes_of(&push), w, h);
    }
}
