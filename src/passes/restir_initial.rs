//! `restir_initial`: per-pixel RIS over the VPL set into a reservoir
//! (shaders/passes/restir_initial.comp). Uniform sampling is its one-candidate case, RIS its
//! M-candidate case; ReSTIR starts from it.

use std::sync::Arc;

use anyhow::Result;
use ash::vk;

use crate::gpu_types::{GpuGridParams, GpuVplParams};
use crate::settings::RestirSettings;
use crate::shaders;
use crate::vk::pipeline::{storage, texels};
use crate::vk::{Buffer, ComputePipeline, Context};

use super::desc::{push_constants, PassDesc};
use super::{FrameTargets, GridBuffers, Reservoirs, VplInputs};

push_constants! {
    /// Also `restir_initial_temporal`'s (the same estimator fused with the temporal merge, which
    /// reads the same thresholds).
    pub struct Push {
        params: GpuVplParams,
        /// The ReGIR grid (`regir_build`); `cells == 0`: none.
        grid: GpuGridParams,
        /// Presampled tiles to read (`vpl_presample`); 0: draw from the VPL buffer.
        tiles: u32,
        /// RIS candidates of a pixel without temporal history: `params.candidates` except in a
        /// ReSTIR frame displayed alone ([`super::VplFrame::candidates_without_history`]).
        candidates_without_history: u32,
        /// `restir_temporal`'s settings, for which pixels have history (when the counts differ).
        mcap: f32,
        normal_threshold: f32,
        depth_threshold: f32,
    }
}

/// Set-1 variant v writes the initial reservoirs to `reservoirs.buffer(v)` and reads the history
/// (for which pixels have it) from the other one.
pub struct RestirInitialPass { pipeline: ComputePipeline }

impl RestirInitialPass {
    pub const NAME: &'static str = "restir_initial";
    pub const DESC: PassDesc = PassDesc::new(Self::NAME, shaders::PASSES_RESTIR_INITIAL, [8, 8, 1])
        .with_raygen(shaders::PASSES_RESTIR_INITIAL_RAYGEN)
        .with_grid(shaders::PASSES_RESTIR_INITIAL_GRID, shaders::PASSES_RESTIR_INITIAL_GRID_RAYGEN)
        .with_workgroup_spec()
        .with_push(Push::LAYOUT)
        .with_bindings(&[
            texels(0, "surfaces"), texels(1, "vpls"), texels(2, "vpl_alias"),
            storage(3, "reservoirs_out"), storage(4, "ray_count"), texels(5, "tiles"),
            texels(6, "grid_entries"), storage(7, "grid_cells"), texels(8, "history"),
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
            .workgroup(targets.workgroup)
            .grid(grid.built)
            .buffers(&[(0, &targets.surfaces), (1, vpls.vpls), (2, vpls.alias), (4, &targets.ray_counter), (5, tiles)])
            .buffers(&[(6, grid.entries), (7, grid.cells)])
            .ping_pong(reservoirs, 3, Some(8))
            .build()?;
        Ok(Self { pipeline })
    }

    /// `tiles`: the presampled tiles to read (0: none, draw from the VPL buffer); `grid`: the
    /// ReGIR grid's parameters (`cells == 0`: none); `without_history`: the candidates of a pixel
    /// without temporal history (`restir`'s thresholds say which), `params.candidates` for none.
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
        out: usize,
        w: u32,
        h: u32,
    ) {
        let push = Push::new(params, grid, tiles, restir, without_history);
        self.pipeline.dispatch_2d_variant(cmd, out, scene_set, bytemuck::bytes_of(&push), w, h);
    }
}

impl Push {
    pub fn new(params: &GpuVplParams, grid: &GpuGridParams, tiles: u32, restir: &RestirSettings, without_history: u32) -> Self {
        Self {
            params: *params,
            grid: *grid,
            tiles,
            candidates_without_history: without_history,
            mcap: restir.mcap,
            normal_threshold: restir.normal_threshold,
            depth_threshold: restir.depth_threshold,
        }
    }
}
