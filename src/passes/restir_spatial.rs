//! `restir_spatial`: merges each pixel's reservoir with random neighbours' reservoirs
//! (shaders/passes/restir_spatial.comp); one dispatch per spatial pass, ping-ponging between
//! `reservoirs_a` and `reservoirs_b`.

use std::sync::Arc;

use anyhow::Result;
use ash::vk;

use crate::gpu_types::GpuVplParams;
use crate::settings::RestirSettings;
use crate::shaders;
use crate::vk::pipeline::{storage, texels};
use crate::vk::{ComputePipeline, Context};

use super::desc::{push_constants, PassDesc};
use super::{FrameTargets, Reservoirs, VplInputs};

push_constants! {
    /// Also `restir_spatial_shade`'s push constants (the same block).
    pub(super) struct Push {
        params: GpuVplParams,
        neighbours: u32,
        radius: f32,
        normal_threshold: f32,
        depth_threshold: f32,
        pass_index: u32,
    }
}

impl Push {
    /// Spatial pass `pass_index`'s constants at image width `w`.
    pub(super) fn new(params: &GpuVplParams, restir: &RestirSettings, pass_index: u32, w: u32) -> Self {
        Self {
            params: *params,
            neighbours: restir.spatial_neighbours,
            radius: restir.spatial_radius_px(w),
            normal_threshold: restir.normal_threshold,
            depth_threshold: restir.depth_threshold,
            pass_index,
        }
    }
}

/// Set-1 variant v reads `reservoirs.buffer(v)` and writes the other one.
pub struct RestirSpatialPass { pipeline: ComputePipeline }

impl RestirSpatialPass {
    pub const NAME: &'static str = "restir_spatial";
    pub const DESC: PassDesc = PassDesc::new(Self::NAME, shaders::PASSES_RESTIR_SPATIAL, [8, 8, 1])
        .with_raygen(shaders::PASSES_RESTIR_SPATIAL_RAYGEN)
        .with_workgroup_spec()
        .with_push(Push::LAYOUT)
        .with_bindings(&[texels(0, "surfaces"), texels(1, "vpls"), texels(2, "src"), storage(3, "dst"), storage(4, "ray_count")]);

    pub fn new(
        ctx: &Arc<Context>,
        scene_layout: vk::DescriptorSetLayout,
        targets: &FrameTargets,
        vpls: &VplInputs,
        reservoirs: &Reservoirs,
    ) -> Result<Self> {
        let pipeline = Self::DESC
            .pipeline(ctx, scene_layout)
            .workgroup(targets.workgroup)
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
        pass_index: u32,
        src: usize,
        w: u32,
        h: u32,
    ) {
        let push = Push::new(params, restir, pass_index, w);
        self.pipeline.dispatch_2d_variant(cmd, src, scene_set, bytemuck::bytes_of(&push), w, h);
    }
}
