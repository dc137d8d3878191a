//! `restir_temporal`: merges the canonical reservoir with the previous frame's final one
//! (shaders/passes/restir_temporal.comp).

use std::sync::Arc;

use anyhow::Result;
use ash::vk;

use crate::gpu_types::GpuVplParams;
use crate::shaders;
use crate::vk::pipeline::storage;
use crate::vk::{Binding, Buffer, ComputePipeline, Context};

use super::{FrameTargets, Reservoirs, VplInputs};

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Push {
    params: GpuVplParams,
    mcap: f32,
}

pub struct RestirTemporalPass {
    pipeline: ComputePipeline,
}

impl RestirTemporalPass {
    pub const NAME: &'static str = "restir_temporal";
    pub const BINDINGS: &'static [Binding] = &[
        storage(0, "surfaces"),
        storage(1, "prev_surfaces"),
        storage(2, "vpls"),
        storage(3, "reservoirs"),
        storage(4, "history"),
        storage(5, "ray_count"),
    ];

    /// Variant v: current = `reservoirs.buffer(v)`, history = the other one. `prev_surfaces`: last
    /// frame's G-buffer (the current one when the pixels do not move).
    pub fn new(
        ctx: &Arc<Context>,
        scene_layout: vk::DescriptorSetLayout,
        targets: &FrameTargets,
        prev_surfaces: &Buffer,
        vpls: &VplInputs,
        reservoirs: &Reservoirs,
    ) -> Result<Self> {
        let pipeline = ComputePipeline::with_variants(
            ctx,
            Self::NAME,
            shaders::PASSES_RESTIR_TEMPORAL,
            scene_layout,
            Self::BINDINGS,
            std::mem::size_of::<Push>() as u32,
            [8, 8, 1],
            2,
        )?;
        let s = &pipeline.set1;
        s.write_buffer(0, &targets.surfaces)?;
        s.write_buffer(1, prev_surfaces)?;
        s.write_buffer(2, vpls.vpls)?;
        s.write_buffer(5, &targets.ray_counter)?;
        for v in 0..2 {
            s.write_buffer_in(v, 3, reservoirs.buffer(v))?;
            s.write_buffer_in(v, 4, reservoirs.buffer(1 - v))?;
        }
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
