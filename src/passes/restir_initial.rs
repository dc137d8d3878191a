//! `restir_initial`: per-pixel RIS over the VPL set into a reservoir
//! (shaders/passes/restir_initial.comp). Uniform sampling is its one-candidate case, RIS its
//! M-candidate case; ReSTIR starts from it.

use std::sync::Arc;

use anyhow::Result;
use ash::vk;

use crate::gpu_types::GpuVplParams;
use crate::shaders;
use crate::vk::pipeline::storage;
use crate::vk::{Binding, ComputePipeline, Context};

use super::{FrameTargets, Reservoirs, VplInputs};

pub struct RestirInitialPass {
    pipeline: ComputePipeline,
}

impl RestirInitialPass {
    pub const NAME: &'static str = "restir_initial";
    pub const BINDINGS: &'static [Binding] = &[
        storage(0, "surfaces"),
        storage(1, "vpls"),
        storage(2, "vpl_alias"),
        storage(3, "reservoirs_out"),
        storage(4, "ray_count"),
    ];

    /// Variant v writes `reservoirs.buffer(v)`.
    pub fn new(
        ctx: &Arc<Context>,
        scene_layout: vk::DescriptorSetLayout,
        targets: &FrameTargets,
        vpls: &VplInputs,
        reservoirs: &Reservoirs,
    ) -> Result<Self> {
        let pipeline = ComputePipeline::with_variants(
            ctx,
            Self::NAME,
            shaders::PASSES_RESTIR_INITIAL,
            scene_layout,
            Self::BINDINGS,
            std::mem::size_of::<GpuVplParams>() as u32,
            [8, 8, 1],
            2,
        )?;
        let s = &pipeline.set1;
        s.write_buffer(0, &targets.surfaces)?;
        s.write_buffer(1, vpls.vpls)?;
        s.write_buffer(2, vpls.alias)?;
        s.write_buffer(4, &targets.ray_counter)?;
        for v in 0..2 {
            s.write_buffer_in(v, 3, reservoirs.buffer(v))?;
        }
        Ok(Self { pipeline })
    }

    pub fn record(&self, cmd: vk::CommandBuffer, scene_set: vk::DescriptorSet, params: &GpuVplParams, out: usize, w: u32, h: u32) {
        self.pipeline.dispatch_2d_variant(cmd, out, scene_set, bytemuck::bytes_of(params), w, h);
    }
}
