//! `vpl_bruteforce`: every VPL with a shadow ray, per pixel (shaders/passes/vpl_bruteforce.comp).
//! Recorded as chunks of VPLs so no single dispatch runs for long.

use std::sync::Arc;

use anyhow::Result;
use ash::vk;

use crate::gpu_types::GpuVplParams;
use crate::shaders;
use crate::vk::pipeline::{compute_barrier, storage, texels};
use crate::vk::{ComputePipeline, Context};

use super::desc::{push_constants, PassDesc};
use super::{FrameTargets, VplInputs};

push_constants! {
    struct Push {
        params: GpuVplParams,
        /// The VPLs `first .. first + count` of this dispatch.
        first: u32,
        count: u32,
    }
}

/// Pixel × VPL pairs per dispatch.
const PAIRS_PER_DISPATCH: u64 = 1 << 24;

pub struct VplBruteforcePass {
    pipeline: ComputePipeline,
    ctx: Arc<Context>,
}

impl VplBruteforcePass {
    pub const NAME: &'static str = "vpl_bruteforce";
    pub const DESC: PassDesc = PassDesc::new(Self::NAME, shaders::PASSES_VPL_BRUTEFORCE, [8, 8, 1])
        .with_raygen(shaders::PASSES_VPL_BRUTEFORCE_RAYGEN)
        .with_workgroup_spec()
        .with_push(Push::LAYOUT)
        .with_bindings(&[texels(0, "surfaces"), storage(1, "vpls"), storage(2, "samples"), storage(3, "ray_count")]);

    pub fn new(ctx: &Arc<Context>, scene_layout: vk::DescriptorSetLayout, targets: &FrameTargets, vpls: &VplInputs) -> Result<Self> {
        let buffers = [(0, &targets.surfaces), (1, vpls.vpls), (2, &targets.samples), (3, &targets.ray_counter)];
        Ok(Self { pipeline: Self::DESC.pipeline(ctx, scene_layout).workgroup(targets.workgroup).buffers(&buffers).build()?, ctx: ctx.clone() })
    }

    pub fn record(&self, cmd: vk::CommandBuffer, scene_set: vk::DescriptorSet, params: &GpuVplParams, w: u32, h: u32) {
        let pixels = (w as u64 * h as u64).max(1);
        let chunk = (PAIRS_PER_DISPATCH / pixels).clamp(1, u32::MAX as u64) as u32;
        let mut first = 0u32;
        loop {
            let push = Push { params: *params, first, count: chunk };
            self.pipeline.dispatch_2d(cmd, scene_set, bytemuck::bytes_of(&push), w, h);
            first = first.saturating_add(chunk);
            if first >= params.vpl_count {
                break;
            }
            compute_barrier(&self.ctx, cmd);
        }
    }
}
