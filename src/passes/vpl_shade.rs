//! `vpl_shade`: Le + c_y(x)·W from the final reservoir, and the reservoir debug views
//! (shaders/passes/vpl_shade.comp).

use std::sync::Arc;

use anyhow::Result;
use ash::vk;

use crate::gpu_types::{GpuVplParams, SHADE_VIEW_FINAL, SHADE_VIEW_RESERVOIR_M, SHADE_VIEW_RESERVOIR_W, SHADE_VIEW_MOTION, SHADE_VIEW_VPL_KIND};
use crate::settings::{RestirSettings, View};
use crate::shaders;
use crate::vk::pipeline::{storage, texels};
use crate::vk::{ComputePipeline, Context};

use super::desc::{push_constants, PassDesc};
use super::{FrameTargets, Reservoirs, VplInputs};

push_constants! {
    struct Push {
        params: GpuVplParams,
        /// `SHADE_VIEW_*`.
        view: u32,
        /// The temporal pass's history tests, for the motion view.
        normal_threshold: f32,
        depth_threshold: f32,
    }
}

/// Set-1 variant v shades from the final reservoirs in `reservoirs.buffer(v)`.
pub struct VplShadePass { pipeline: ComputePipeline }

impl VplShadePass {
    pub const NAME: &'static str = "vpl_shade";
    pub const DESC: PassDesc = PassDesc::new(Self::NAME, shaders::PASSES_VPL_SHADE, [8, 8, 1])
        .with_raygen(shaders::PASSES_VPL_SHADE_RAYGEN)
        .with_workgroup_spec()
        .with_push(Push::LAYOUT)
        .with_bindings(&[
            texels(0, "surfaces"), texels(1, "vpls"), texels(2, "reservoirs"),
            storage(3, "samples"), storage(4, "ray_count"),
        ]);

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
            .buffers(&[(0, &targets.surfaces), (1, vpls.vpls), (3, &targets.samples), (4, &targets.ray_counter)])
            .ping_pong(reservoirs, 2, None)
            .build()?;
        Ok(Self { pipeline })
    }

    /// The shader's `SHADE_VIEW_*` code of a view (the views it does not draw itself are final).
    fn view_code(view: View) -> u32 {
        match view {
            View::ReservoirW => SHADE_VIEW_RESERVOIR_W,
            View::ReservoirM => SHADE_VIEW_RESERVOIR_M,
            View::VplKind => SHADE_VIEW_VPL_KIND,
            View::Motion => SHADE_VIEW_MOTION,
            _ => SHADE_VIEW_FINAL,
        }
    }

    #[allow(clippy::too_many_arguments)]
    pub fn record(
        &self,
        cmd: vk::CommandBuffer,
        scene_set: vk::DescriptorSet,
        params: &GpuVplParams,
        view: View,
        restir: &RestirSettings,
        reservoir: usize,
        w: u32,
        h: u32,
    ) {
        let push = Push {
            params: *params,
            view: Self::view_code(view),
            normal_threshold: restir.normal_threshold,
            depth_threshold: restir.depth_threshold,
        };
        self.pipeline.dispatch_2d_variant(cmd, reservoir, scene_set, bytemuck::bytes_of(&push), w, h);
    }
}
