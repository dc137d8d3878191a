//! `restir_spatial`: merges each pixel's reservoir with random neighbours' reservoirs
//! (shaders/passes/restir_spatial.comp); one dispatch per spatial pass, ping-ponging between
//! `reservoirs_a` and `reservoirs_b`.

use std::sync::Arc;

use anyhow::Result;
use ash::vk;

use crate::gpu_types::{GpuVplParams, VPL_FLAG_INITIAL_VISIBILITY, VPL_FLAG_UNBIASED};
use crate::settings::RestirSettings;
use crate::shaders;
use crate::vk::pipeline::{storage, texels};
use crate::vk::{ComputePipeline, Context};

use super::desc::{push_constants, PassDesc};
use super::{FrameTargets, Reservoirs, VplInputs};

push_constants! {
    /// Also `restir_spatial_shade`'s push constants (the same block).
    pub(super) struct Push {
        params: GpuVplParams,
        neighbours: u32,
        neighbours_without_history: u32,
        radius: f32,
        normal_threshold: f32,
        depth_threshold: f32,
        pass_index: u32,
    }
}

impl Push {
    /// Spatial pass `pass_index`'s constants at image width `w`; `without_history`: the neighbours
    /// of a pixel whose reservoir has no temporal history ([`super::VplFrame::neighbours_without_history`]).
    pub(super) fn new(params: &GpuVplParams, restir: &RestirSettings, without_history: u32, pass_index: u32, w: u32) -> Self {
        Self {
            params: *params,
            neighbours: restir.spatial_neighbours,
            neighbours_without_history: without_history,
            radius: restir.spatial_radius_px(w),
            normal_threshold: restir.normal_threshold,
            depth_threshold: restir.depth_threshold,
            pass_index,
        }
    }
}

/// The specialisation constants of `restir_spatial` and `restir_spatial_shade`: the reuse's kind
/// (spatial_merge's `unbiased` and `visible_targets`), fixed per pipeline so that the driver
/// compiles only the branch it runs.
pub(super) const REUSE_CONSTANTS: &[(u32, &str)] = &[(2, "UNBIASED"), (3, "VISIBLE_TARGETS")];

/// The reuse's kind the VPL flags `flags` ask for: (unbiased, visibility in the targets).
pub(super) fn reuse_kind(flags: u32) -> (bool, bool) {
    let unbiased = flags & VPL_FLAG_UNBIASED != 0;
    (unbiased, unbiased && flags & VPL_FLAG_INITIAL_VISIBILITY != 0)
}

/// Sets [`REUSE_CONSTANTS`] on a spatial pass's pipeline for the VPL flags `flags`.
pub(super) fn with_reuse_kind(b: super::desc::PipelineBuilder<'_>, flags: u32) -> super::desc::PipelineBuilder<'_> {
    let (unbiased, visible) = reuse_kind(flags);
    b.constant("UNBIASED", unbiased.into()).constant("VISIBLE_TARGETS", visible.into())
}

/// Set-1 variant v reads `reservoirs.buffer(v)` and writes the other one. Built for one reuse kind
/// (`flags`, the VPL flags it is then pushed).
pub struct RestirSpatialPass { pipeline: ComputePipeline, flags: u32 }

impl RestirSpatialPass {
    pub const NAME: &'static str = "restir_spatial";
    pub const DESC: PassDesc = PassDesc::new(Self::NAME, shaders::PASSES_RESTIR_SPATIAL, [8, 8, 1])
        .with_raygen(shaders::PASSES_RESTIR_SPATIAL_RAYGEN)
        .with_workgroup_spec()
        .with_constants(REUSE_CONSTANTS)
        .with_push(Push::LAYOUT)
        .with_bindings(&[texels(0, "surfaces"), texels(1, "vpls"), texels(2, "src"), storage(3, "dst"), storage(4, "ray_count")]);

    /// `flags`: the VPL flags (`GpuVplParams::flags`) every `record` will push.
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
            .buffers(&[(0, &targets.surfaces), (1, vpls.vpls), (4, &targets.ray_counter)])
            .ping_pong(reservoirs, 2, Some(3))
            .build()?;
        Ok(Self { pipeline, flags })
    }

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
        debug_assert_eq!(reuse_kind(params.flags), reuse_kind(self.flags), "restir_spatial was built for other VPL flags");
        let push = Push::new(params, restir, without_history, pass_index, w);
        self.pipeline.dispatch_2d_variant(cmd, src, scene_set, bytemuck::bytes_of(&push), w, h);
    }
}
