//! `restir_initial_temporal`: `restir_initial` and `restir_temporal` fused into one dispatch
//! (shaders/passes/restir_initial_temporal.comp), as Bevy Solari runs ReSTIR DI: the same
//! functions and random streams, so the same estimator, without the initial reservoirs' trip
//! through memory or a second read of the surface. The frame plan uses it when both passes would
//! run and no frame capture needs the initial reservoirs (`--fuse-passes`).

use std::sync::Arc;

use anyhow::Result;
use ash::vk;

use crate::gpu_types::{GpuGridParams, GpuVplParams};
use crate::settings::RestirSettings;
use crate::shaders;
use crate::vk::pipeline::{storage, texels};
use crate::vk::{Buffer, ComputePipeline, Context};

use super::desc::PassDesc;
// restir_initial's push constants: the same estimator, so the same parameters.
use super::restir_initial::Push;
use super::{FrameTargets, GridBuffers, Reservoirs, VplInputs};

/// Set-1 variant v writes this frame's reservoirs to `reservoirs.buffer(v)` and reads the history
/// from the other one.
pub struct RestirInitialTemporalPass { pipeline: ComputePipeline }

impl RestirInitialTemporalPass {
    pub const NAME: &'static str = "restir_initial_temporal";
    /// Fixed 8×8, as `restir_temporal`.
    pub const DESC: PassDesc = PassDesc::new(Self::NAME, shaders::PASSES_RESTIR_INITIAL_TEMPORAL, [8, 8, 1])
        .with_raygen(shaders::PASSES_RESTIR_INITIAL_TEMPORAL_RAYGEN)
        .with_grid(shaders::PASSES_RESTIR_INITIAL_TEMPORAL_GRID, shaders::PASSES_RESTIR_INITIAL_TEMPORAL_GRID_RAYGEN)
        .with_push(Push::LAYOUT)
        .with_bindings(&[
            texels(0, "surfaces"), texels(1, "vpls"), texels(2, "vpl_alias"), texels(3, "tiles"),
            texels(4, "history"), storage(5, "reservoirs_out"), storage(6, "ray_count"),
            texels(7, "grid_entries"), storage(8, "grid_cells"),
        ]);

    pub fn new(
        ctx: &Arc<Context>,
        scene_layout: vk::DescriptorSetLayout,
        targets: &FrameTargets,
        vpls: &VplInputs,
        reservoirs: &Reservoirs,
        tiles: &Buffer,
        grid: &GridBuffers,
    ) -> Result<Self> {
        let pipeline = Self::DESC
            .pipeline(ctx, scene_layout)
            .grid(grid.built)
            .buffers(&[(0, &targets.surfaces), (1, vpls.vpls), (2, vpls.alias), (3, tiles), (6, &targets.ray_counter)])
            .buffers(&[(7, grid.entries), (8, grid.cells)])
            .ping_pong(reservoirs, 5, Some(4))
            .build()?;
        Ok(Self { pipeline })
    }

    /// `tiles`: the presampled tiles to read (0: none); `grid`: the ReGIR grid (`cells == 0`:
    /// none); `without_history`: the candidates of a pixel without temporal history; `current`:
    /// the reservoir buffer written.
    #[allow(clippy::too_many_arguments)]
    pub fn record(
        &self,
        cmd: vk::CommandBuffer,
        scene_set: vk::DescriptorSet,
        params: &GpuVplParams,
        grid: &GpuGridParams,
        tiles: u32,
        restir: &RestirSettings,
        without_history: u32,
        current: usize,
        w: u32,
        h: u32,
    ) {
        let push = Push::new(params, grid, tiles, restir, without_history);
        self.pipeline.dispatch_2d_variant(cmd, current, scene_set, bytemuck::bytes_of(&push), w, h);
    }
}
