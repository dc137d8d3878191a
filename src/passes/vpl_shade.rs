//! `vpl_shade`: Le + c_y(x)·W from the final reservoir, and the reservoir debug views
//! (shaders/passes/vpl_shade.comp).

use std::sync::Arc;

use anyhow::Result;
use ash::vk;

use crate::gpu_types::GpuVplParams;
use crate::settings::View;
use crate::shaders;
use crate::vk::pipeline::storage;
use crate::vk::{Binding, ComputePipeline, Context};

use super::{FrameTargets, Reservoirs, VplInputs};

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Push {
    params: GpuVplParams,
    view: u32,
}

pub struct VplShadePass {
    pipeline: ComputePipeline,
}

impl VplShadePass {
    pub const NAME: &'static str = "vpl_shade";
    pub const BINDINGS: &'static [Binding] = &[
        storage(0, "surfaces"),
        storage(1, "vpls"),
        storage(2, "reservoirs"),
        storage(3, "samples"),
        storage(4, "ray_count"),
    ];

    /// Variant v reads `reservoirs.buffer(v)`.
    pub fn new(
        ctx: &Arc<Context>,
        scene_layout: vk::DescriptorSetLayout,
        targets: &FrameTargets,
        vpls: &VplInputs,
        reservoirs: &Reservoirs,
    ) -> Result<Self> {
        let pipeline = ComputePipeline::with_variants(
            ctx,
            Self::NAME,
            shaders::PASSES_VPL_SHADE,
            scene_layout,
            Self::BINDINGS,
            std::mem::size_of::<Push>() as u32,
            [8, 8, 1],
            2,
        )?;
        let s = &pipeline.set1;
        s.write_buffer(0, &targets.surfaces)?;
        s.write_buffer(1, vpls.vpls)?;
        s.write_buffer(3, &targets.samples)?;
        s.write_buffer(4, &targets.ray_counter)?;
        for v in 0..2 {
            s.write_buffer_in(v, 2, reservoirs.buffer(v))?;
        }
        Ok(Self { pipeline })
    }

    /// The shader's view code.
    fn view_code(view: View) -> u32 {
        match view {
            View::ReservoirW => 1,
            View::ReservoirM => 2,
            View::VplKind => 3,
            _ => 0,
        }
    }

    #[allow(clippy::too_many_arguments)]
    pub fn record(
        &self,
        cmd: vk::CommandBuffer,
        scene_set: vk::DescriptorSet,
        params: &GpuVplParams,
        view: View,
        reservoir: usize,
        w: u32,
        h: u32,
    ) {
        let push = Push { params: *params, view: Self::view_code(view) };
        self.pipeline.dispatch_2d_variant(cmd, reservoir, scene_set, bytemuck::bytes_of(&push), w, h);
    }
}
