//! `vpl_presample`: fills the frame's tiles of presampled VPL candidates
//! (shaders/passes/vpl_presample.comp) that `restir_initial` reads instead of the whole VPL buffer
//! (RTXDI's light presampling).

use std::sync::Arc;

use anyhow::Result;
use ash::vk;
use gpu_allocator::MemoryLocation;

use crate::gpu_types::{GpuVplCandidate, GpuVplParams, PRESAMPLE_MAX_TILES, PRESAMPLE_TILE_SIZE};
use crate::shaders;
use crate::vk::pipeline::{storage, texels};
use crate::vk::{Buffer, ComputePipeline, Context};

use super::desc::{push_constants, PassDesc};
use super::VplInputs;

push_constants! {
    struct Push {
        params: GpuVplParams,
        /// Tiles to fill (each `PRESAMPLE_TILE_SIZE` candidates).
        tiles: u32,
    }
}

/// Owns the tile buffer (`vpl_presample.tiles`) that `restir_initial` reads.
pub struct VplPresamplePass {
    pipeline: ComputePipeline,
    pub tiles: Buffer,
    pub tile_count: u32,
}

impl VplPresamplePass {
    pub const NAME: &'static str = "vpl_presample";
    pub const DESC: PassDesc = PassDesc::new(Self::NAME, shaders::PASSES_VPL_PRESAMPLE, [64, 1, 1])
        .with_push(Push::LAYOUT)
        .with_bindings(&[texels(0, "vpls"), texels(1, "vpl_alias"), storage(2, "tiles")]);

    /// Tiles for an image: `PRESAMPLE_MAX_TILES` (RTXDI: 128 tiles of 1024), fewer for images of
    /// fewer 8×8 blocks (a tiny image would spend more on drawing tiles than on reading them).
    pub fn tile_count(width: u32, height: u32) -> u32 {
        (width.div_ceil(8) * height.div_ceil(8)).clamp(1, PRESAMPLE_MAX_TILES)
    }

    pub fn new(ctx: &Arc<Context>, scene_layout: vk::DescriptorSetLayout, vpls: &VplInputs, width: u32, height: u32) -> Result<Self> {
        let tile_count = Self::tile_count(width, height);
        let bytes = (tile_count * PRESAMPLE_TILE_SIZE) as u64 * std::mem::size_of::<GpuVplCandidate>() as u64;
        let tiles = Self::tiles_buffer(ctx, "vpl_presample.tiles", bytes)?;
        let pipeline = Self::DESC.pipeline(ctx, scene_layout).buffers(&[(0, vpls.vpls), (1, vpls.alias), (2, &tiles)]).build()?;
        Ok(Self { pipeline, tiles, tile_count })
    }

    /// A tiles buffer of `bytes`: written as storage here, read by `restir_initial` as texels
    /// (two per candidate; shaders/common/texel_records.glsl says why).
    pub fn tiles_buffer(ctx: &Arc<Context>, name: &str, bytes: u64) -> Result<Buffer> {
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC;
        Buffer::new(ctx, name, bytes, usage, MemoryLocation::GpuOnly)?.with_texel_view(super::RECORD_TEXELS)
    }

    pub fn record(&self, cmd: vk::CommandBuffer, scene_set: vk::DescriptorSet, params: &GpuVplParams) {
        let push = Push { params: *params, tiles: self.tile_count };
        self.pipeline.dispatch_1d(cmd, scene_set, bytemuck::bytes_of(&push), self.tile_count * PRESAMPLE_TILE_SIZE);
    }
}
