//! `restir_temporal`: merges the canonical reservoir with the previous frame's final one
//! (shaders/passes/restir_temporal.comp).

use std::sync::Arc;

use anyhow::Result;
use ash::vk;

use crate::gpu_types::GpuVplParams;
use crate::shaders;
use crate::vk::pipeline::{storage, texels};
use crate::settings::RestirSettings;
use crate::vk::{ComputePipeline, Context};

use super::desc::{push_constants, PassDesc};
use super::{FrameTargets, Reservoirs, VplInputs};

push_constants! {
    struct Push {
        params: GpuVplParams,
        mcap: f32,
        normal_threshold: f32,
        depth_threshold: f32,
    }
}

/// Set-1 variant v: current = `reservoirs.buffer(v)`, history = the other one.
pub struct RestirTemporalPass { pipeline: ComputePipeline }

impl RestirTemporalPass {
    pub const NAME: &'static str = "restir_temporal";
    /// Fixed 8×8: it does not take `--workgroup` (docs/workgroups.md measured it at 8×8).
    pub const DESC: PassDesc = PassDesc::new(Self::NAME, shaders::PASSES_RESTIR_TEMPORAL, [8, 8, 1])
        .with_raygen(shaders::PASSES_RESTIR_TEMPORAL_RAYGEN)
        .with_push(Push::LAYOUT)
        .with_bindings(&[
            texels(0, "surfaces"), texels(1, "vpls"), storage(2, "reservoirs"), texels(3, "history"),
            storage(4, "ray_count"),
        ]);

    /// `targets.surfaces` holds both halves of the G-buffer ping-pong (this frame's and the
    /// previous frame's, picked by the frame constants).
    pub fn new(
        ctx: &Arc<Context>,
        scene_layout: vk::DescriptorSetLayout,
        targets: &FrameTargets,
        vpls: &VplInputs,
        reservoirs: &Reservoirs,
    ) -> Result<Self> {
        let pipeline = Self::DESC
            .pipeline(ctx, scene_layout)
            .buffers(&[(0, &targets.surfaces), (1, vpls.vpls), (4, &targets.ray_counter)])
            .ping_pong(reservoirs, 2, Some(3))
            .build()?;
        Ok(Self { pipeline })
    }

    #[allow(clippy::too_many_arguments)]
    pub fn record(
        &self,
        cmd: vk::CommandBuffer,
        scene_set: vk::DescriptorSet,
        params: &GpuVplParams,
        restir: &RestirSettings,
        current: usize,
        w: u32,
        h: u32,
    ) {
        let push = Push {
            params: *params,
            mcap: restir.mcap,
            normal_threshold: restir.normal_threshold,
            depth_threshold: restir.depth_threshold,
        };
        self.pipeline.dispatch_2d_variant(cmd, current, scene_set, bytemuck::bytes_of(&push), w, h);
    }
}
