//! `regir_build`: fills the world-space grid of presampled VPLs (ReGIR) that `restir_initial`
//! draws part of its candidates from (shaders/passes/regir_build.comp; the estimator is in
//! shaders/restir/regir.glsl). One workgroup per cell; only the cells a pixel asked for in the
//! previous frame are built.

use std::sync::Arc;

use anyhow::Result;
use ash::vk;
use gpu_allocator::MemoryLocation;
use glam::Vec3;

use crate::gpu_types::{GpuGridEntry, GpuGridParams, GpuVplParams, GRID_FLAG_BALANCE, REGIR_WORKGROUP};
use crate::settings::GridSettings;
use crate::shaders;
use crate::vk::pipeline::{storage, texels};
use crate::vk::{Buffer, ComputePipeline, Context};

use super::desc::{push_constants, PassDesc};
use super::VplInputs;

push_constants! {
    struct Push {
        params: GpuVplParams,
        grid: GpuGridParams,
    }
}

/// Owns the grid: `regir.entries` (`GpuGridEntry` per cell × entry, read by `restir_initial` as
/// texels) and `regir.cells` (per cell: the frame a pixel last asked for it, the frame it was
/// built in, and its normalisation of this and the previous build).
pub struct RegirBuildPass {
    pipeline: ComputePipeline,
    pub entries: Buffer,
    pub cells: Buffer,
    pub params: GpuGridParams,
}

impl RegirBuildPass {
    pub const NAME: &'static str = "regir_build";
    pub const DESC: PassDesc = PassDesc::new(Self::NAME, shaders::PASSES_REGIR_BUILD, [REGIR_WORKGROUP, 1, 1])
        .with_push(Push::LAYOUT)
        .with_bindings(&[texels(0, "vpls"), texels(1, "vpl_alias"), storage(2, "entries"), storage(3, "cells")]);

    /// The grid over the scene's bounds `(lo, hi)`, grown by 1 % of the diagonal on each side so
    /// that every surface point lies strictly inside a cell (a receiver outside the grid takes no
    /// grid candidates, which is unbiased but wastes them).
    pub fn grid_params(bounds: (Vec3, Vec3), grid: &GridSettings) -> GpuGridParams {
        let (lo, hi) = bounds;
        let pad = Vec3::splat(0.01 * (hi - lo).length().max(1e-6));
        let (lo, hi) = (lo - pad, hi + pad);
        // No axis thinner than a hundredth of the longest (a flat scene would get zero-size cells).
        let extent = (hi - lo).max(Vec3::splat((hi - lo).max_element() * 0.01));
        GpuGridParams {
            lo: lo.to_array(),
            cells: grid.cells,
            cell_size: (extent / grid.cells as f32).to_array(),
            entries: grid.entries,
            entry_candidates: grid.entry_candidates,
            grid_candidates: grid.candidates,
            flags: if grid.balance { GRID_FLAG_BALANCE } else { 0 },
            _pad1: 0,
        }
    }

    /// Bytes of the entries buffer of `grid`.
    pub fn entries_bytes(grid: &GridSettings) -> u64 {
        u64::from(grid.cells).pow(3) * u64::from(grid.entries) * std::mem::size_of::<GpuGridEntry>() as u64
    }

    pub fn new(ctx: &Arc<Context>, scene_layout: vk::DescriptorSetLayout, vpls: &VplInputs, bounds: (Vec3, Vec3), grid: &GridSettings) -> Result<Self> {
        let limits = &ctx.properties.limits;
        let bytes = Self::entries_bytes(grid);
        let texels = bytes / super::RECORD_TEXELS.bytes;
        anyhow::ensure!(
            bytes <= u64::from(limits.max_storage_buffer_range) && texels <= u64::from(limits.max_texel_buffer_elements),
            "--grid-cells {} --grid-entries {}: the grid's entries take {bytes} bytes, more than this device's buffer limits \
             (maxStorageBufferRange {} bytes, maxTexelBufferElements {}); use fewer cells or entries",
            grid.cells,
            grid.entries,
            limits.max_storage_buffer_range,
            limits.max_texel_buffer_elements
        );
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER
            | vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER
            | vk::BufferUsageFlags::TRANSFER_SRC
            | vk::BufferUsageFlags::TRANSFER_DST;
        let entries = Buffer::new(ctx, "regir.entries", bytes, usage, MemoryLocation::GpuOnly)?.with_texel_view(super::RECORD_TEXELS)?;
        // Zeros until a cell is built: a cell never built holds no stale memory, which
        // --check-finite and --dump-passes read with the rest of the grid.
        // SAFETY: the buffer is alive and unused; one_shot waits for the fill.
        ctx.one_shot(|cmd| unsafe { ctx.device.cmd_fill_buffer(cmd, entries.raw, 0, vk::WHOLE_SIZE, 0) })?;
        // Zero records: never asked for, never built, no normalisation yet.
        let cells_bytes = vec![0u8; grid.cells.pow(3) as usize * 16];
        let cells = Buffer::with_data(ctx, "regir.cells", &cells_bytes, vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC)?;
        let pipeline = Self::DESC.pipeline(ctx, scene_layout).buffers(&[(0, vpls.vpls), (1, vpls.alias), (2, &entries), (3, &cells)]).build()?;
        Ok(Self { pipeline, entries, cells, params: Self::grid_params(bounds, grid) })
    }

    pub fn record(&self, cmd: vk::CommandBuffer, scene_set: vk::DescriptorSet, params: &GpuVplParams) {
        let push = Push { params: *params, grid: self.params };
        let n = self.params.cells;
        self.pipeline.dispatch(cmd, scene_set, bytemuck::bytes_of(&push), [n, n, n]);
    }
}
