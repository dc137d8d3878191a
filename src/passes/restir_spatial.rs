//! `restir_spatial`: merges each pixel's reservoir with random neighbours' reservoirs
//! (shaders/passes/restir_spatial.comp); one dispatch per spatial pass, ping-ponging between
//! `reservoirs_a` and `reservoirs_b`.

use std::sync::Arc;

use anyhow::Result;
use ash::vk;

use crate::gpu_types::GpuVplParams;
use crate::settings::RestirSettings;
use crate::shaders;
use crate::vk::pipeline::storage;
use crate::vk::{Binding, ComputePipeline, Context};

use super::{FrameTargets, Reservoirs, VplInputs};

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Push {
    params: GpuVplParams,
    neighbours: u32,
    radius: f32,
    normal_threshold: f32,
    depth_threshold: f32,
    pass_index: u32,
}

pub struct RestirSpatialPass {
    pipeline: ComputePipeline,
}

impl RestirSpatialPass {
    pub const NAME: &'static str = "restir_spatial";
    pub const BINDINGS: &'static [Binding] =
        &[storage(0, "surfaces"), storage(1, "vpls"), storage(2, "src"), storage(3, "dst"), storage(4, "ray_count")];

    /// Variant v reads `reservoirs.buffer(v)` and writes the other one.
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
            shaders::PASSES_RESTIR_SPATIAL,
            scene_layout,
            Self::BINDINGS,
            std::mem::size_of::<Push>() as u32,
            [8, 8, 1],
            2,
        )?;
        let s = &pipeline.set1;
        s.write_buffer(0, &targets.surfaces)?;
        s.write_buffer(1, vpls.vpls)?;
        s.write_buffer(4, &targets.ray_counter)?;
        for v in 0..2 {
            s.write_buffer_in(v, 2, reservoirs.buffer(v))?;
            s.write_buffer_in(v, 3, reservoirs.buffer(1 - v))?;
        }
        Ok(Self { pipeline })
    }

    #[allow(clippy::too_many_arguments)]
    pub fn record(
        &self,
        cmd: vk::CommandBuffer,
        scene_set: vk::DescriptorSet,
        params: &GpuVplParams,
        restir: &RestirSettings,
        pass_index: u32,
        src: usize,
        w: u32,
        h: u32,
    ) {
        let push = Push {
            params: *params,
            neighbours: restir.spatial_neighbours,
            radius: restir.spatial_radius,
            normal_threshold: restir.normal_threshold,
            depth_threshold: restir.depth_threshold,
            pass_index,
        };
        self.pipeline.dispatch_2d_variant(cmd, src, scene_set, bytemuck::bytes_of(&push), w, h);
    }
}
