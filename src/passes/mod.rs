//! The frame, pass by pass. Each pass is `src/passes/<name>.rs` + `shaders/passes/<name>.comp`, owns
//! its pipeline and set-1 bindings, and is recorded inside a debug label and GPU timestamp scope of
//! the same name. [`Passes::record_frame`] is the whole frame on one screen.

pub mod accumulate;
pub mod gbuffer;
pub mod pathtrace;
pub mod photon_emit;
pub mod tonemap;
pub mod vpl_view;

use std::sync::Arc;

use anyhow::Result;
use ash::vk;
use gpu_allocator::MemoryLocation;

use crate::gpu_types::GpuSurface;
use crate::vk::pipeline::compute_barrier;
use crate::vk::{Buffer, Context, GpuTimer};

pub use accumulate::AccumulatePass;
pub use gbuffer::GbufferPass;
pub use pathtrace::PathtracePass;
pub use photon_emit::{PhotonEmitPass, PhotonSettings, PhotonStats};
pub use tonemap::TonemapPass;
pub use vpl_view::VplViewPass;

/// Per-pixel buffers shared between passes.
pub struct FrameTargets {
    pub width: u32,
    pub height: u32,
    /// `GpuSurface` per pixel (gbuffer output).
    pub surfaces: Buffer,
    /// This frame's radiance estimate per pixel (vec4).
    pub samples: Buffer,
    pub accum_sum: Buffer,
    pub accum_compensation: Buffer,
    pub accum_squares: Buffer,
    /// Running mean (vec4).
    pub mean: Buffer,
    /// RGBA8 sRGB preview.
    pub preview: Buffer,
    /// Rays traced this frame by the sampling passes (reset every frame).
    pub ray_counter: Buffer,
    /// Whole-run statistics: non-finite sample count.
    pub stats: Buffer,
}

impl FrameTargets {
    pub fn new(ctx: &Arc<Context>, width: u32, height: u32) -> Result<Self> {
        let n = width as u64 * height as u64;
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER
            | vk::BufferUsageFlags::TRANSFER_SRC
            | vk::BufferUsageFlags::TRANSFER_DST;
        let make = |name: &str, bytes: u64| Buffer::new(ctx, name, bytes, storage, MemoryLocation::GpuOnly);
        Ok(Self {
            width,
            height,
            surfaces: make("gbuffer.surfaces", n * std::mem::size_of::<GpuSurface>() as u64)?,
            samples: make("frame.samples", n * 16)?,
            accum_sum: make("accumulate.sum", n * 16)?,
            accum_compensation: make("accumulate.compensation", n * 16)?,
            accum_squares: make("accumulate.squares", n * 16)?,
            mean: make("accumulate.mean", n * 16)?,
            preview: make("tonemap.preview", n * 4)?,
            ray_counter: make("frame.ray_counter", 16)?,
            stats: make("frame.stats", 16)?,
        })
    }

    pub fn pixels(&self) -> u32 {
        self.width * self.height
    }
}

/// Whether a pass runs this frame, and why not when it does not.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Step {
    Run,
    Skip(&'static str),
}

/// The frame's pass list, decided before recording (printed with `--verbose`).
#[derive(Clone, Debug)]
pub struct FramePlan {
    pub gbuffer: Step,
    pub pathtrace: Step,
    pub vpl_view: Step,
    pub accumulate: Step,
    pub tonemap: Step,
    /// Start a new accumulation (first frame, or after a change).
    pub reset_accumulation: bool,
}

impl FramePlan {
    pub fn steps(&self) -> [(&'static str, &Step); 5] {
        [
            (GbufferPass::NAME, &self.gbuffer),
            (PathtracePass::NAME, &self.pathtrace),
            (VplViewPass::NAME, &self.vpl_view),
            (AccumulatePass::NAME, &self.accumulate),
            (TonemapPass::NAME, &self.tonemap),
        ]
    }

    /// One line per pass: `run` or `skip (why)`.
    pub fn describe(&self) -> String {
        self.steps()
            .iter()
            .map(|(name, step)| match step {
                Step::Run => format!("  {name:<12} run"),
                Step::Skip(why) => format!("  {name:<12} skip ({why})"),
            })
            .collect::<Vec<_>>()
            .join("\n")
    }
}

/// Every pass of the renderer.
pub struct Passes {
    pub gbuffer: GbufferPass,
    pub pathtrace: PathtracePass,
    pub accumulate: AccumulatePass,
    pub tonemap: TonemapPass,
    /// Only with `--view vpls`.
    pub vpl_view: Option<VplViewPass>,
}

impl Passes {
    pub fn new(ctx: &Arc<Context>, scene_layout: vk::DescriptorSetLayout, targets: &FrameTargets) -> Result<Self> {
        Ok(Self {
            gbuffer: GbufferPass::new(ctx, scene_layout, targets)?,
            pathtrace: PathtracePass::new(ctx, scene_layout, targets)?,
            accumulate: AccumulatePass::new(ctx, scene_layout, targets)?,
            tonemap: TonemapPass::new(ctx, scene_layout, targets)?,
            vpl_view: None,
        })
    }

    /// Records one frame: the pass order of the renderer, in one place.
    pub fn record_frame(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        timer: &mut GpuTimer,
        scene_set: vk::DescriptorSet,
        targets: &FrameTargets,
        plan: &FramePlan,
    ) {
        let (w, h, pixels) = (targets.width, targets.height, targets.pixels());
        // SAFETY: cmd is recording; the counter buffers are alive for the frame.
        unsafe {
            ctx.device.cmd_fill_buffer(cmd, targets.ray_counter.raw, 0, vk::WHOLE_SIZE, 0);
            if plan.reset_accumulation {
                ctx.device.cmd_fill_buffer(cmd, targets.stats.raw, 0, vk::WHOLE_SIZE, 0);
            }
        }
        compute_barrier(ctx, cmd);

        scoped(ctx, cmd, timer, &plan.gbuffer, GbufferPass::NAME, |cmd| self.gbuffer.record(cmd, scene_set, w, h));
        scoped(ctx, cmd, timer, &plan.pathtrace, PathtracePass::NAME, |cmd| self.pathtrace.record(cmd, scene_set, w, h));
        if let Some(view) = &self.vpl_view {
            scoped(ctx, cmd, timer, &plan.vpl_view, VplViewPass::NAME, |cmd| view.record(cmd, scene_set, pixels));
        }
        scoped(ctx, cmd, timer, &plan.accumulate, AccumulatePass::NAME, |cmd| {
            self.accumulate.record(cmd, scene_set, pixels, plan.reset_accumulation)
        });
        scoped(ctx, cmd, timer, &plan.tonemap, TonemapPass::NAME, |cmd| self.tonemap.record(cmd, scene_set, pixels));
    }
}

/// Runs `record` inside a label + timestamp scope named `name`, followed by a barrier, if the
/// plan says the pass runs.
fn scoped(
    ctx: &Context,
    cmd: vk::CommandBuffer,
    timer: &mut GpuTimer,
    step: &Step,
    name: &'static str,
    record: impl FnOnce(vk::CommandBuffer),
) {
    if *step != Step::Run {
        return;
    }
    timer.begin(cmd, name);
    record(cmd);
    timer.end(cmd);
    compute_barrier(ctx, cmd);
}
