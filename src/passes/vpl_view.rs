//! `vpl_view`: the VPL debug image — diffuse-shaded scene with every VPL drawn as a small sphere
//! (blue direct, red indirect), splatted against the G-buffer depth (shaders/passes/vpl_view.comp).

use std::sync::Arc;

use anyhow::Result;
use ash::vk;
use gpu_allocator::MemoryLocation;

use crate::gpu_types::{VPL_VIEW_CLEAR, VPL_VIEW_DEPTH, VPL_VIEW_DRAW, VPL_VIEW_ID};
use crate::shaders;
use crate::vk::pipeline::{compute_barrier, storage, texels};
use crate::vk::{Buffer, ComputePipeline, Context};

use super::desc::{push_constants, PassDesc};
use super::FrameTargets;

push_constants! {
    struct Push {
        /// `VPL_VIEW_*`: the step of this dispatch.
        mode: u32,
        vpl_count: u32,
        radius: f32,
        /// Largest splat half-width (pixels).
        max_footprint: u32,
    }
}

/// Largest splat half-width in pixels: a sphere's image is cut to a square this many pixels either
/// side of its centre, so that one VPL near the camera costs at most (2 × 48 + 1)² pixel tests.
pub const VPL_VIEW_MAX_FOOTPRINT: u32 = 48;

pub struct VplViewPass {
    pipeline: ComputePipeline,
    _sphere_t: Buffer,
    _sphere_id: Buffer,
    vpl_count: u32,
    radius: f32,
    ctx: Arc<Context>,
}

impl VplViewPass {
    pub const NAME: &'static str = "vpl_view";
    pub const DESC: PassDesc = PassDesc::new(Self::NAME, shaders::PASSES_VPL_VIEW, [64, 1, 1])
        .with_push(Push::LAYOUT)
        .with_bindings(&[
            texels(0, "surfaces"), texels(1, "vpls"), storage(2, "sphere_t"),
            storage(3, "sphere_id"), storage(4, "samples"),
        ]);

    /// `radius`: sphere radius in scene units.
    pub fn new(
        ctx: &Arc<Context>,
        scene_layout: vk::DescriptorSetLayout,
        targets: &FrameTargets,
        vpls: &Buffer,
        vpl_count: u32,
        radius: f32,
    ) -> Result<Self> {
        let n = targets.pixels() as u64 * 4;
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let sphere_t = Buffer::new(ctx, "vpl_view.sphere_t", n, usage, MemoryLocation::GpuOnly)?;
        let sphere_id = Buffer::new(ctx, "vpl_view.sphere_id", n, usage, MemoryLocation::GpuOnly)?;
        let pipeline = Self::DESC
            .pipeline(ctx, scene_layout)
            .buffers(&[(0, &targets.surfaces), (1, vpls), (2, &sphere_t), (3, &sphere_id), (4, &targets.samples)])
            .build()?;
        Ok(Self { pipeline, _sphere_t: sphere_t, _sphere_id: sphere_id, vpl_count, radius, ctx: ctx.clone() })
    }

    pub fn record(&self, cmd: vk::CommandBuffer, scene_set: vk::DescriptorSet, pixels: u32) {
        // Clear per pixel, splat the nearest sphere depth then its VPL id per VPL, draw per pixel.
        let steps = [(VPL_VIEW_CLEAR, pixels), (VPL_VIEW_DEPTH, self.vpl_count), (VPL_VIEW_ID, self.vpl_count), (VPL_VIEW_DRAW, pixels)];
        for (i, (mode, items)) in steps.into_iter().enumerate() {
            if i > 0 {
                compute_barrier(&self.ctx, cmd);
            }
            let push = Push { mode, vpl_count: self.vpl_count, radius: self.radius, max_footprint: VPL_VIEW_MAX_FOOTPRINT };
            self.pipeline.dispatch_1d(cmd, scene_set, bytemuck::bytes_of(&push), items);
        }
    }
}
