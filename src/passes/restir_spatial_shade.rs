//! `restir_spatial_shade`: the last `restir_spatial` pass and `vpl_shade` fused into one dispatch
//! (shaders/passes/restir_spatial_shade.comp), as Bevy Solari runs ReSTIR DI: the same functions
//! and random streams, so the same estimator, without reading the final reservoirs back or the
//! surface twice. The frame plan uses it when both would run, the view is the shaded image and no
//! frame capture needs the last spatial pass's output on its own (`--fuse-passes`).

use std::sync::Arc;

use anyhow::Result;
use ash::vk;

use crate::gpu_types::GpuVplParams;
use crate::settings::RestirSettings;
use crate::shaders;
use crate::vk::pipeline::{storage, texels};
use crate::vk::{ComputePipeline, Context};

use super::desc::PassDesc;
use super::restir_spatial::{reuse_kind, with_reuse_kind, Push, REUSE_CONSTANTS};
use super::{FrameTargets, Reservoirs, VplInputs};

/// Set-1 variant v reads `reservoirs.buffer(v)` and writes the other one (then shades it). Built
/// for one reuse kind, as `restir_spatial`.
pub struct RestirSpatialShadePass { pipeline: ComputePipeline, flags: u32 }

impl RestirSpatialShadePass {
    pub const NAME: &'static str = "restir_spatial_shade";
    pub const DESC: PassDesc = PassDesc::new(Self::NAME, shaders::PASSES_RESTIR_SPATIAL_SHADE, [8, 8, 1])
        .with_raygen(shaders::PASSES_RESTIR_SPATIAL_SHADE_RAYGEN)
        .with_workgroup_spec()
        .with_constants(REUSE_CONSTANTS)
        .with_push(Push::LAYOUT)
        .with_bindings(&[
            texels(0, "surfaces"), texels(1, "vpls"), texels(2, "src"), storage(3, "dst"),
            storage(4, "samples"), storage(5, "ray_count"),
        ]);

    pub fn new(
        ctx: &Arc<Context>,
        scene_layout: vk::DescriptorSetLayout,
        targets: &FrameTargets,
        vpls: &VplInputs,
        reservoirs: &Reservoirs,
        flags: u32,
    ) -> Result<Self> {
        let pipeline = with_reuse_kind(Self::DESC.pipeline(ctx, scene_layout), flags)
            .workgroup(targets.workgroup)
            .buffers(&[(0, &targets.surfaces), (1, vpls.vpls), (4, &targets.samples), (5, &targets.ray_counter)])
            .ping_pong(reservoirs, 2, Some(3))
            .build()?;
        Ok(Self { pipeline, flags })
    }

    /// `pass_index`: the spatial pass this is (the last one), `src`: the buffer it reads.
    #[allow(clippy::too_many_arguments)]
    pub fn record(
        &self,
        cmd: vk::CommandBuffer,
        scene_set: vk::DescriptorSet,
        params: &GpuVplParams,
        restir: &RestirSettings,
        without_history: u32,
        pass_index: u32,
        src: usize,
        w: u32,
        h: u32,
    ) {
        debug_assert_eq!(reuse_kind(params.flags), reuse_kind(self.flags), "restir_spatial_shade was built for other VPL flags");
        let push = Push::new(params, restir, without_history, pass_index, w);
        self.pipeline.dispatch_2d_variant(cmd, src, scene_set, bytemuck::bytes_of(&push), w, h);
    }
}
