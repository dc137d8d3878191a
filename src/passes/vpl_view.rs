//! `vpl_view`: the VPL debug image — diffuse-shaded scene with every VPL drawn as a small sphere
//! (blue direct, red indirect), splatted against the G-buffer depth (shaders/passes/vpl_view.comp).

use std::sync::Arc;

use anyhow::Result;
use ash::vk;
use gpu_allocator::MemoryLocation;

use crate::shaders;
use crate::vk::pipeline::{compute_barrier, storage};
use crate::vk::{Binding, Buffer, ComputePipeline, Context};

use super::FrameTargets;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Push {
    mode: u32,
    vpl_count: u32,
    radius: f32,
    max_footprint: u32,
}

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
    pub const BINDINGS: &'static [Binding] = &[
        storage(0, "surfaces"),
        storage(1, "vpls"),
        storage(2, "sphere_t"),
        storage(3, "sphere_id"),
        storage(4, "samples"),
    ];

    /// `radius`: sphere radius in scene units.
    pub fn new(
        ctx: &Arc<Context>,
        scene_layout: vk::DescriptorSetLayout,
        targets: &FrameTargets,
        vpls: &Buffer,
        vpl_count: u32,
        radius: f32,
    ) -> Result<Self> {
        let pipeline = ComputePipeline::new(
            ctx,
            Self::NAME,
            shaders::PASSES_VPL_VIEW,
            scene_layout,
            Self::BINDINGS,
            std::mem::size_of::<Push>() as u32,
            [64, 1, 1],
        )?;
        let n = targets.pixels() as u64 * 4;
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let sphere_t = Buffer::new(ctx, "vpl_view.sphere_t", n, usage, MemoryLocation::GpuOnly)?;
        let sphere_id = Buffer::new(ctx, "vpl_view.sphere_id", n, usage, MemoryLocation::GpuOnly)?;
        let s = &pipeline.set1;
        s.write_buffer(0, &targets.surfaces)?;
        s.write_buffer(1, vpls)?;
        s.write_buffer(2, &sphere_t)?;
        s.write_buffer(3, &sphere_id)?;
        s.write_buffer(4, &targets.samples)?;
        Ok(Self { pipeline, _sphere_t: sphere_t, _sphere_id: sphere_id, vpl_count, radius, ctx: ctx.clone() })
    }

    pub fn record(&self, cmd: vk::CommandBuffer, scene_set: vk::DescriptorSet, pixels: u32) {
        for mode in 0..4u32 {
            let push = Push { mode, vpl_count: self.vpl_count, radius: self.radius, max_footprint: 48 };
            let items = if mode == 1 || mode == 2 { self.vpl_count } else { pixels };
            self.pipeline.dispatch_1d(cmd, scene_set, bytemuck::bytes_of(&push), items);
            if mode < 3 {
                compute_barrier(&self.ctx, cmd);
            }
        }
    }
}
