//! `gbuffer`: primary rays -> one `GpuSurface` per pixel, stored packed (`GpuSurfaceTexels`)
//! through `GBUFFER_CHUNKS` storage-buffer bindings of the G-buffer (shaders/passes/gbuffer.comp).

use std::sync::Arc;

use anyhow::Result;
use ash::vk;

use crate::shaders;
use crate::gpu_types::{GpuSurfaceTexels, GBUFFER_CHUNKS};
use crate::vk::pipeline::storage;
use crate::vk::{ComputePipeline, Context};

use super::desc::{push_constants, PassDesc};
use super::FrameTargets;

push_constants! {
    struct Push {
        /// Records per chunk binding (`FrameTargets::surface_chunk_records()`).
        chunk_records: u32,
    }
}

pub struct GbufferPass {
    pipeline: ComputePipeline,
    chunk_records: u32,
}

impl GbufferPass {
    pub const NAME: &'static str = "gbuffer";
    pub const DESC: PassDesc = PassDesc::new(Self::NAME, shaders::PASSES_GBUFFER, [8, 8, 1])
        .with_raygen(shaders::PASSES_GBUFFER_RAYGEN)
        .with_textured_raygen(shaders::PASSES_GBUFFER_TEXTURED_RAYGEN)
        .with_workgroup_spec()
        .with_textured(shaders::PASSES_GBUFFER_TEXTURED)
        .with_push(Push::LAYOUT)
        .with_bindings(&[
            storage(0, "surfaces_chunk0"), storage(1, "surfaces_chunk1"), storage(2, "surfaces_chunk2"),
            storage(3, "surfaces_chunk3"), storage(4, "surfaces_chunk4"), storage(5, "surfaces_chunk5"),
            storage(6, "surfaces_chunk6"), storage(7, "surfaces_chunk7"),
        ]);

    /// `textured`: the scene set has textures bound (see `SceneGpu::textured`).
    pub fn new(ctx: &Arc<Context>, scene_layout: vk::DescriptorSetLayout, textured: bool, targets: &FrameTargets) -> Result<Self> {
        let chunk_records = targets.surface_chunk_records();
        let chunk_bytes = u64::from(chunk_records) * std::mem::size_of::<GpuSurfaceTexels>() as u64;
        let ranges: Vec<_> = (0..GBUFFER_CHUNKS).map(|c| (c, &targets.surfaces, u64::from(c) * chunk_bytes, chunk_bytes)).collect();
        let pipeline =
            Self::DESC.pipeline(ctx, scene_layout).workgroup(targets.workgroup).textured(textured).buffer_ranges(&ranges).build()?;
        Ok(Self { pipeline, chunk_records })
    }

    pub fn record(&self, cmd: vk::CommandBuffer, scene_set: vk::DescriptorSet, width: u32, height: u32) {
        let push = Push { chunk_records: self.chunk_records };
        self.pipeline.dispatch_2d(cmd, scene_set, bytemuck::bytes_of(&push), width, height);
    }
}
