//! The renderer: one call renders one frame of a shared, already uploaded scene for a given camera.
//! It owns the frame targets, the passes its settings need, the VPL set (traced once, since the
//! scene is static) and per-frame-slot resources (command buffer, fence, timestamps, frame
//! constants), and it keeps the one log of frame times and rays that headless runs, benchmarks,
//! the error study and the window all read.

use std::collections::BTreeMap;
use std::rc::Rc;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context as _, Result};
use ash::vk;
use glam::Vec3;
use gpu_allocator::MemoryLocation;

use crate::camera::Camera;
use crate::gpu_types::{
    GpuFrame, GpuVplParams, COMPENSATE_EMISSION, COMPENSATE_VPLS, ATTENUATION_INVERSE_SQUARE, ATTENUATION_YUKSEL, FRAME_AA, KIND_MASK_DIRECT,
    KIND_MASK_INDIRECT, VPL_FLAG_INITIAL_VISIBILITY, VPL_FLAG_PER_VPL_RADIUS, VPL_FLAG_SAME_DOMAIN, VPL_FLAG_UNBIASED,
};
use crate::output::TimingStats;
use crate::passes::{
    FramePlan, FrameTargets, GridBuffers, Passes, PhotonEmitPass, PhotonStats, RegirBuildPass, Reservoirs, RestirBoilingPass, RestirInitialPass, RestirInitialTemporalPass,
    RestirSpatialPass, RestirSpatialShadePass, RestirTemporalPass, Step, VplBruteforcePass, VplCompensatePass, VplFrame, VplInputs, VplPresamplePass, VplShadePass, VplViewPass, RAY_COUNTER_WORDS, RAY_SLOTS,
};
use crate::lights::{LightSet, PointEmitter};
use crate::scene_gpu::{LightBuffers, SceneGpu};
use crate::settings::{Attenuation, Bias, CandidateSource, Mode, RenderSettings, View};
use crate::vk::buffer::{read_back, read_back_records};
use crate::vk::context::Tracing;
use crate::vk::{Buffer, Context, DescriptorSet, GpuTimer};

/// Statistics of one rendered frame.
#[derive(Clone, Debug, Default)]
pub struct FrameStats {
    /// (pass, GPU ms) of every dispatch in recording order: a repeated pass once per dispatch
    /// ([`FrameStats::pass_ms`] sums them per pass).
    pub dispatch_ms: Vec<(&'static str, f64)>,
    /// Rays traced this frame (primary + sampling passes).
    pub rays: u64,
    /// Rays per tracing pass this frame (primary rays under "gbuffer").
    pub rays_by_pass: Vec<(&'static str, u64)>,
    /// Wall-clock time from the start of recording to the frame's completion.
    pub wall_ms: f64,
    /// ReSTIR ran with the sampling of a frame displayed alone
    /// ([`RenderSettings::moving_sampling`]).
    pub moving: bool,
}

impl FrameStats {
    /// GPU time of the frame: the sum of its pass scopes.
    pub fn gpu_ms(&self) -> f64 {
        self.dispatch_ms.iter().map(|p| p.1).sum()
    }

    /// (pass, GPU ms) in recording order; a pass dispatched several times (restir_spatial ×n)
    /// appears once with the sum.
    pub fn pass_ms(&self) -> Vec<(&'static str, f64)> {
        let mut out: Vec<(&'static str, f64)> = Vec::new();
        for &(name, ms) in &self.dispatch_ms {
            match out.iter_mut().find(|(n, _)| *n == name) {
                Some(entry) => entry.1 += ms,
                None => out.push((name, ms)),
            }
        }
        out
    }
}

/// The frames rendered since the log was last cleared: what every caller reports from.
#[derive(Clone, Debug, Default)]
pub struct FrameLog {
    pixels: f64,
    /// GPU ms per frame (sum of its pass scopes).
    pub gpu_ms: Vec<f64>,
    pub wall_ms: Vec<f64>,
    /// Rays per frame.
    pub rays: Vec<u64>,
    /// GPU ms per pass, one entry per frame the pass ran in.
    pub pass_ms: BTreeMap<&'static str, Vec<f64>>,
    /// Rays per tracing pass, one entry per frame it traced in.
    pub pass_rays: BTreeMap<&'static str, Vec<u64>>,
    /// Frames that ran with the sampling of a frame displayed alone ([`FrameStats::moving`]).
    pub moving_frames: u32,
}

impl FrameLog {
    fn push(&mut self, s: &FrameStats) {
        self.gpu_ms.push(s.gpu_ms());
        self.wall_ms.push(s.wall_ms);
        self.rays.push(s.rays);
        for (name, ms) in s.pass_ms() {
            self.pass_ms.entry(name).or_default().push(ms);
        }
        for (name, n) in &s.rays_by_pass {
            self.pass_rays.entry(name).or_default().push(*n);
        }
        self.moving_frames += u32::from(s.moving);
    }

    pub fn frames(&self) -> usize {
        self.gpu_ms.len()
    }

    pub fn gpu(&self) -> TimingStats {
        TimingStats::of(&self.gpu_ms)
    }

    pub fn wall(&self) -> TimingStats {
        TimingStats::of(&self.wall_ms)
    }

    /// Rays per pixel per frame.
    pub fn rays_per_pixel(&self) -> TimingStats {
        TimingStats::of(&self.rays.iter().map(|&n| n as f64 / self.pixels).collect::<Vec<_>>())
    }

    /// GPU ms per pass over the frames it ran in.
    pub fn pass_stats(&self) -> BTreeMap<String, TimingStats> {
        self.pass_ms.iter().map(|(k, v)| (k.to_string(), TimingStats::of(v))).collect()
    }

    /// GPU ms of each pass's first dispatch in the log. On a driver that compiles a shader when it
    /// is first dispatched (lavapipe), and whose cache is cold, it holds the compilation.
    pub fn first_pass_ms(&self) -> BTreeMap<String, f64> {
        self.pass_ms.iter().filter_map(|(k, v)| Some((k.to_string(), *v.first()?))).collect()
    }

    /// GPU ms per pass over the frames it ran in after its first ([`Self::first_pass_ms`]); an
    /// empty (count 0) entry for a pass that ran once.
    pub fn pass_stats_after_first(&self) -> BTreeMap<String, TimingStats> {
        self.pass_ms.iter().map(|(k, v)| (k.to_string(), TimingStats::of(v.get(1..).unwrap_or_default()))).collect()
    }

    /// Rays per pixel per frame, by the pass that traced them, over every frame of the log (0 in
    /// the frames a pass did not trace in), so that the passes' means add up to
    /// [`Self::rays_per_pixel`]'s.
    pub fn rays_per_pixel_by_pass(&self) -> BTreeMap<String, TimingStats> {
        self.pass_rays
            .iter()
            .map(|(k, v)| {
                let mut per_pixel: Vec<f64> = v.iter().map(|&n| n as f64 / self.pixels).collect();
                per_pixel.resize(per_pixel.len().max(self.frames()), 0.0);
                (k.to_string(), TimingStats::of(&per_pixel))
            })
            .collect()
    }
}

/// How the VPL modes shade: the VPL set's size and the parameters every VPL pass gets (reported
/// through [`VplSummary`]).
struct VplSetup {
    vpl_count: u32,
    /// Yuksel's r actually used (scene units), when the attenuation is Yuksel's.
    yuksel_radius: Option<f32>,
    /// Where the radius came from.
    yuksel_radius_source: Option<String>,
    params: GpuVplParams,
    /// `vpl_compensate`'s parameters (its own candidate count) and `COMPENSATE_*` bits; the bits
    /// are 0 when the pass does not run (no `--compensate`, or a view that is not light).
    compensate: (GpuVplParams, u32),
    _alias: Buffer,
    /// Bound as `restir_initial`'s tiles when there is no `vpl_presample` pass.
    _no_tiles: Option<Buffer>,
    /// Bound as `restir_initial`'s grid (entries, cells) when there is no `regir_build` pass.
    _no_grid: Option<(Buffer, Buffer)>,
    reservoirs: Option<Reservoirs>,
    /// What the VPL set made moot (said on stderr as it was decided; the run's summary keeps it):
    /// the power source over VPLs without power, `--yuksel-knn` over a set too small for it.
    notes: Vec<String>,
}

/// A run with `--candidate-source power` whose VPLs carry no power says so (stderr and the summary),
/// and draws its candidates uniformly.
pub const POWERLESS_VPLS: &str = "--candidate-source power: the VPLs carry no power (an empty VPL set or no emitters), so the candidates are drawn uniformly; no VPL lights anything either way";

/// What summary.json reports about the VPL shading.
#[derive(Clone, Debug, serde::Serialize)]
pub struct VplSummary {
    pub vpl_count: u32,
    pub yuksel_radius: Option<f32>,
    pub yuksel_radius_source: Option<String>,
    /// RIS candidates drawn by restir_initial (1 = uniform sampling).
    pub candidates: u32,
    /// "uniform" or "power".
    pub candidate_source: &'static str,
    /// Candidates come from `vpl_presample`'s tiles.
    pub presample: bool,
    /// The ReGIR grid that `grid.candidates` of the candidates come from (None: no grid).
    pub grid: Option<crate::settings::GridSettings>,
    /// Of the grid's cells, those `regir_build` built in the last frame (the cells its pixels lay
    /// in the frame before); filled by [`Renderer::grid_cells_built`].
    pub grid_cells_built: Option<u32>,
    /// Targets include visibility (initial sample shadow-tested).
    pub initial_visibility: bool,
    pub unbiased_reuse: bool,
    /// The spatial reuse disc's radius in pixels (given, or scaled with the width); None without
    /// spatial reuse.
    pub spatial_radius_px: Option<f32>,
    /// ReSTIR with temporal reuse: [candidates, spatial neighbours] of a frame displayed alone
    /// while temporal reuse has history ([`RenderSettings::moving_sampling`]).
    pub moving_sampling: Option<[u32; 2]>,
    /// Frames of the log that ran with them.
    pub moving_frames: u32,
}

/// What the first ray of `vpl_compensate` carries for `view` (`COMPENSATE_*` bits; 0: nothing,
/// the pass does not run): the direct image misses the light of emitters near x; the indirect
/// image the VPL light near x and everything after it; without GI there is no indirect light.
pub fn compensate_first_hop(view: View, gi: bool) -> u32 {
    let vpls = if gi { COMPENSATE_VPLS } else { 0 };
    match view {
        View::Final => COMPENSATE_EMISSION | vpls,
        View::Direct => COMPENSATE_EMISSION,
        View::Indirect => vpls,
        _ => 0,
    }
}

/// Largest pixel × VPL product a brute-force frame accepts (~2 h on lavapipe, seconds on a GPU).
pub const MAX_BRUTEFORCE_PAIRS: u64 = 20_000_000_000;

/// Refuses a brute-force frame of more than [`MAX_BRUTEFORCE_PAIRS`] pixel × VPL pairs, naming
/// the flags that change it.
fn check_bruteforce_pairs(settings: &RenderSettings, vpls: u64) -> Result<()> {
    let pairs = bruteforce_pairs(settings, vpls);
    anyhow::ensure!(
        pairs <= MAX_BRUTEFORCE_PAIRS,
        "--mode bruteforce: {}×{} pixels × {vpls} VPLs = {pairs} shadow rays per frame, over the limit of \
         {MAX_BRUTEFORCE_PAIRS}; use a smaller image (--width/--height) or fewer VPLs (--vpls-direct/--vpls-indirect)",
        settings.width,
        settings.height
    );
    Ok(())
}

/// Pixel × VPL pairs (shadow rays) of one brute-force frame of `settings` over `vpls` VPLs.
pub fn bruteforce_pairs(settings: &RenderSettings, vpls: u64) -> u64 {
    u64::from(settings.width) * u64::from(settings.height) * vpls
}

/// Frames that may be recorded while earlier ones still run on the GPU.
pub const FRAME_SLOTS: usize = 2;

/// Everything one frame in flight owns: its command buffer and fence, timestamp queries, the
/// counter read-back, its frame constants and the set 0 variant that points at them.
/// Frees its command buffer and fence when dropped: after [`Renderer`]'s own Drop has waited for
/// idle, or at once when `Renderer::new` fails after making it.
struct FrameSlot {
    ctx: Arc<Context>,
    cmd: vk::CommandBuffer,
    fence: vk::Fence,
    timer: GpuTimer,
    readback: Buffer,
    frame_constants: Buffer,
    /// The frame waiting for this slot's fence.
    pending: Option<PendingFrame>,
}

/// What [`Renderer::complete_frame`] needs of a submitted frame once its fence signals.
#[derive(Clone, Copy, Debug)]
struct PendingFrame {
    /// When the frame was begun (its wall time runs from here to the fence).
    start: Instant,
    gbuffer_ran: bool,
    /// It restarted the accumulation, and with it the GPU's non-finite count.
    reset: bool,
    /// Its frame index (a wait that takes long names it).
    frame: u32,
    /// It drew the sampling of a frame displayed alone.
    moving: bool,
}

/// Accumulation and reuse state carried from frame to frame.
#[derive(Clone, Copy, Debug, Default)]
struct FrameState {
    /// Frames rendered since the accumulation started.
    accumulated: u32,
    /// Frames rendered in total (RNG frame index).
    frame_index: u32,
    gbuffer_valid: bool,
    /// Which half of the G-buffer ping-pong holds the current surfaces (0 or 1).
    surface_half: u32,
    /// Reservoir buffer that receives the next frame's initial reservoirs (0 = a, 1 = b).
    current_reservoirs: usize,
    /// The other reservoir buffer holds a previous frame's final reservoirs.
    history_valid: bool,
    /// Non-finite samples replaced by zero in this accumulation (counted by the accumulate pass).
    nonfinite_samples: u64,
}

/// The parts of a renderer its settings decide.
struct Parts {
    /// Draws with the textured shader variants.
    textured: bool,
    /// Shared with the next `Parts` when a settings change keeps the size.
    targets: Rc<FrameTargets>,
    passes: Passes,
    /// The VPL set, when the run needs one: traced once before the first frame (static scene).
    photons: Option<(PhotonEmitPass, PhotonStats)>,
    /// The VPL shading setup, in the VPL modes.
    vpl: Option<VplSetup>,
}

pub struct Renderer {
    settings: RenderSettings,
    scene: Arc<SceneGpu>,
    /// Set 0: one variant per frame slot (the scene, plus that slot's frame constants).
    scene_set: DescriptorSet,
    /// The lights: the scene's plus `extra_lights` (set 0 bindings 6 and 7).
    lights: LightBuffers,
    extra_lights: Vec<PointEmitter>,
    /// What the settings decide (rebuilt by [`Renderer::apply_settings`]).
    parts: Parts,
    slots: Vec<FrameSlot>,
    next_slot: usize,
    /// The camera of the last frame recorded.
    camera: Option<Camera>,
    state: FrameState,
    /// Non-finite samples replaced by zero since the renderer was made, over every accumulation
    /// (the GPU's count restarts with each: a camera path, a view that shows frames alone).
    nonfinite_total: u64,
    log: FrameLog,
    last_stats: FrameStats,
    /// Host-visible buffer the captured pass outputs are copied into (`--dump-passes`,
    /// `--check-finite`); allocated on first use.
    capture_buffer: Option<Buffer>,
    /// The pass list of the last frame recorded (what ran, what was skipped and why).
    last_plan: Option<FramePlan>,
    /// Tests only (`RESTIR_VPL_DEBUG_POISON=vpl_shade`): a pass writes a NaN, so that
    /// `--check-finite` can be shown to find it (`=validation`: see [`record_invalid_command`]).
    debug_poison: u32,
    /// Tests only (`RESTIR_VPL_DEBUG_POISON=hang_after:<pass>`): every frame, after that pass, waits
    /// for an event the host never sets, so that a frame that never finishes can be shown to end
    /// in an error naming the passes finished (`Context::wait_fence`).
    debug_hang: Option<(&'static str, vk::Event)>,
    ctx: Arc<Context>,
}

/// `RESTIR_VPL_DEBUG_POISON=hang_after:<pass>` (tests only; `poison`: the variable's value): the
/// event a frame waits on after that pass ([`Renderer::debug_hang`]).
fn debug_hang(ctx: &Context, poison: Option<&str>) -> Result<Option<(&'static str, vk::Event)>> {
    let Some(pass) = poison.and_then(|p| p.strip_prefix("hang_after:")) else { return Ok(None) };
    let name = crate::passes::ALL_PASSES
        .iter()
        .map(|d| d.name)
        .find(|n| *n == pass)
        .with_context(|| format!("RESTIR_VPL_DEBUG_POISON=hang_after:{pass}: no pass of that name"))?;
    // SAFETY: valid device.
    let event = unsafe { ctx.device.create_event(&vk::EventCreateInfo::default(), None) }.context("vkCreateEvent")?;
    ctx.set_name(event, "debug_poison.hang");
    Ok(Some((name, event)))
}

/// Records the wait of [`Renderer::debug_hang`] after its pass's dispatch `d`.
fn record_debug_hang(ctx: &Context, cmd: vk::CommandBuffer, d: crate::passes::Dispatch, hang: Option<(&'static str, vk::Event)>) {
    if let Some((pass, event)) = hang.filter(|(pass, _)| *pass == d.name) {
        log::warn!("RESTIR_VPL_DEBUG_POISON: the frame waits after {pass} for an event that is never set");
        // SAFETY: cmd is recording; the event is alive and unsignalled (the host never sets it).
        unsafe {
            ctx.device.cmd_wait_events(cmd, &[event], vk::PipelineStageFlags::HOST, vk::PipelineStageFlags::ALL_COMMANDS, &[], &[], &[]);
        }
    }
}

/// Tests only (`RESTIR_VPL_DEBUG_POISON=validation`): one command the validation layer reports, so
/// that a command's failure on validation errors can be shown. vkCmdFillBuffer on a buffer created
/// without TRANSFER_DST usage (VUID-vkCmdFillBuffer-dstBuffer-00029); drivers ignore usage flags, so
/// it is harmless.
fn record_invalid_command(ctx: &Arc<Context>) -> Result<()> {
    let buffer = Buffer::new(ctx, "debug_poison.validation", 256, vk::BufferUsageFlags::STORAGE_BUFFER, MemoryLocation::GpuOnly)?;
    // SAFETY: cmd is recording; the buffer outlives the one-shot submission.
    ctx.one_shot(|cmd| unsafe { ctx.device.cmd_fill_buffer(cmd, buffer.raw, 0, 256, 0) })
}

/// What a captured pass output holds: a record per pixel, or per entry of a buffer that is not an
/// image (`vpl_presample`'s tiles, `regir_build`'s grid).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CaptureKind {
    /// `GpuSurfaceTexels` (the G-buffer's packed record; `decode` gives the `GpuSurface`).
    Surfaces,
    /// RGBA f32 (samples, the running mean).
    Rgba,
    /// `GpuReservoir`.
    Reservoirs,
    /// RGBA8 sRGB (the preview).
    Rgba8,
    /// `GpuVplCandidate`, one per tile entry (`vpl_presample`'s tiles): not per pixel.
    Candidates,
    /// `GpuGridEntry`, one per cell entry (`regir_build`'s grid, every cell: those not built this
    /// frame keep an earlier build's entries, or zeros): not per pixel.
    GridEntries,
}

impl CaptureKind {
    pub fn bytes_per_record(self) -> u64 {
        match self {
            CaptureKind::Surfaces => std::mem::size_of::<crate::gpu_types::GpuSurfaceTexels>() as u64,
            CaptureKind::Rgba => 16,
            CaptureKind::Reservoirs => std::mem::size_of::<crate::gpu_types::GpuReservoir>() as u64,
            CaptureKind::Rgba8 => 4,
            CaptureKind::Candidates => std::mem::size_of::<crate::gpu_types::GpuVplCandidate>() as u64,
            CaptureKind::GridEntries => std::mem::size_of::<crate::gpu_types::GpuGridEntry>() as u64,
        }
    }

    /// Whether the records are the image's pixels (row-major), as every kind but the tiles' and
    /// the grid's are.
    pub fn per_pixel(self) -> bool {
        self.group().is_none()
    }

    /// What a row of [`Captured::shape`] is for a capture that is not per pixel: a presampled
    /// tile, a grid cell.
    pub fn group(self) -> Option<&'static str> {
        match self {
            CaptureKind::Candidates => Some("tile"),
            CaptureKind::GridEntries => Some("cell"),
            _ => None,
        }
    }
}

/// One pass's output as it stood right after the pass ran.
#[derive(Clone, Debug)]
pub struct Captured {
    /// Position in the frame among the dispatches that ran (0-based).
    pub position: usize,
    pub pass: &'static str,
    /// Which dispatch of a repeated pass (`restir_spatial` ×P).
    pub repeat: u32,
    /// The buffer's name in the code (the binding the pass writes).
    pub buffer: &'static str,
    pub kind: CaptureKind,
    /// The scene's [`crate::scene::Scene::origin`]: the bytes hold positions in the renderer's
    /// coordinates, which the dump's images show moved back into the file's.
    pub origin: glam::Vec3,
    /// The records as an image, [columns, rows]: the frame's width and height for a per-pixel
    /// output, [entries per tile, tiles] for `vpl_presample`'s tiles, [entries per cell, cells]
    /// for `regir_build`'s grid.
    pub shape: [u32; 2],
    pub bytes: Vec<u8>,
}

impl Captured {
    pub fn records(&self) -> usize {
        self.shape[0] as usize * self.shape[1] as usize
    }
}

/// A captured output's place in the capture buffer.
#[derive(Clone, Copy, Debug)]
struct CaptureMeta {
    position: usize,
    pass: &'static str,
    repeat: u32,
    buffer: &'static str,
    kind: CaptureKind,
    shape: [u32; 2],
    offset: u64,
    size: u64,
}

/// What a dispatch writes that a capture copies: its buffer's name, kind, shape (as
/// [`Captured::shape`]), source buffer and byte offset in it.
struct DispatchOutput<'a> {
    buffer: &'static str,
    kind: CaptureKind,
    shape: [u32; 2],
    src: &'a Buffer,
    offset: u64,
}

impl DispatchOutput<'_> {
    fn size(&self) -> u64 {
        self.kind.bytes_per_record() * u64::from(self.shape[0]) * u64::from(self.shape[1])
    }
}

/// Where a dispatch's output lies among the renderer's `parts` (None: the pass writes nothing a
/// capture copies).
fn dispatch_output(d: crate::passes::Dispatch, parts: &Parts, current: usize, surface_half: u32) -> Option<DispatchOutput<'_>> {
    use crate::passes::*;
    let targets = &parts.targets;
    let reservoirs = parts.vpl.as_ref().and_then(|v| v.reservoirs.as_ref());
    let (presample, regir) = (parts.passes.vpl.presample.as_ref(), parts.passes.vpl.regir.as_ref());
    let image = [targets.width, targets.height];
    let out = |buffer, kind, src, offset| DispatchOutput { buffer, kind, shape: image, src, offset };
    Some(match d.name {
        GbufferPass::NAME => out(
            "surfaces",
            CaptureKind::Surfaces,
            &targets.surfaces,
            u64::from(surface_half) * u64::from(targets.surface_half_records) * CaptureKind::Surfaces.bytes_per_record(),
        ),
        PathtracePass::NAME | VplBruteforcePass::NAME | VplShadePass::NAME | VplCompensatePass::NAME | VplViewPass::NAME => out("samples", CaptureKind::Rgba, &targets.samples, 0),
        // The frame's tiles of presampled candidates (a NaN there was blamed on restir_initial).
        VplPresamplePass::NAME => {
            let p = presample?;
            DispatchOutput { buffer: "tiles", kind: CaptureKind::Candidates, shape: [crate::gpu_types::PRESAMPLE_TILE_SIZE, p.tile_count], src: &p.tiles, offset: 0 }
        }
        RegirBuildPass::NAME => {
            let g = regir?;
            DispatchOutput { buffer: "entries", kind: CaptureKind::GridEntries, shape: [g.params.entries, g.params.cells.pow(3)], src: &g.entries, offset: 0 }
        }
        // (The fused passes never run in a captured frame: FramePlan splits them.)
        RestirInitialPass::NAME | RestirTemporalPass::NAME | RestirBoilingPass::NAME => out("reservoirs", CaptureKind::Reservoirs, reservoirs?.buffer(current), 0),
        // Spatial pass j reads buffer(current ^ (j & 1)) and writes the other one.
        RestirSpatialPass::NAME => out("reservoirs", CaptureKind::Reservoirs, reservoirs?.buffer(1 - (current ^ (d.repeat as usize & 1))), 0),
        AccumulatePass::NAME => out("mean", CaptureKind::Rgba, &targets.mean, 0),
        TonemapPass::NAME => out("preview", CaptureKind::Rgba8, &targets.preview, 0),
        _ => return None,
    })
}

/// `settings` checked (`validate`, [`check_tracing`]) and resolved: `--fuse-passes` not given
/// (None) becomes on ([`RenderSettings::fuses_passes`]), so that the renderer's settings, and the
/// summary written from them, say which ran.
fn settings_for_device(ctx: &Context, mut settings: RenderSettings) -> Result<RenderSettings> {
    settings.fuse_passes = Some(settings.fuses_passes());
    settings.validate()?;
    check_tracing(ctx, &settings)?;
    Ok(settings)
}

/// Settings that the context's way of tracing rays cannot run: launches larger than a
/// ray-tracing pipeline allows, or settings made for the other way of tracing.
fn check_tracing(ctx: &Context, settings: &RenderSettings) -> Result<()> {
    ctx.check_launch_size(settings.width, settings.height)?;
    // The settings' way of tracing is the context's (the context was made for it; a renderer
    // given another context would trace the context's way without a word).
    if let Some(asked) = settings.tracing {
        anyhow::ensure!(
            asked == ctx.tracing,
            "--trace {}: this renderer's device context traces with {}",
            asked.name(),
            ctx.tracing.describe()
        );
    }
    if let Some(w) = tracing_workgroup_warning(ctx, settings) {
        log::warn!("{w}");
    }
    Ok(())
}

/// `--workgroup` with ray-tracing pipelines: on stderr at the set-up, and in the run's summary.
fn tracing_workgroup_warning(ctx: &Context, settings: &RenderSettings) -> Option<String> {
    (ctx.tracing == Tracing::Pipeline && settings.workgroup != RenderSettings::default().workgroup).then(|| {
        format!(
            "--workgroup {}x{} has no effect here: every pass it sizes traces rays, and runs as a ray-generation shader \
             (ray-tracing pipelines), whose launch has no workgroups",
            settings.workgroup[0], settings.workgroup[1]
        )
    })
}

impl Renderer {
    /// A renderer of `scene` (uploaded once by the caller and shared) with `settings`: frame
    /// targets, the passes the settings use and, when they need VPLs, the photon pass's VPL set.
    pub fn new(ctx: Arc<Context>, scene: Arc<SceneGpu>, settings: RenderSettings) -> Result<Self> {
        let settings = settings_for_device(&ctx, settings)?;
        if let Some(why) = crate::camera::scene_camera_problem(&scene.info, settings.camera.as_ref(), settings.camera_path.is_some()) {
            anyhow::bail!(why);
        }
        // Tests only: a fault to plant (record_invalid_command, POISON_VPL_SHADE, debug_hang).
        let poison = std::env::var("RESTIR_VPL_DEBUG_POISON").ok();
        if poison.as_deref() == Some("validation") {
            record_invalid_command(&ctx)?;
        }
        let scene_set = DescriptorSet::with_variants(&ctx, "scene", scene.bindings, FRAME_SLOTS as u32)?;
        scene.write_set(&scene_set)?;
        let mut buffers = Vec::with_capacity(FRAME_SLOTS);
        for i in 0..FRAME_SLOTS {
            let frame_constants = Buffer::new(
                &ctx,
                &format!("frame{i}.constants"),
                std::mem::size_of::<GpuFrame>() as u64,
                vk::BufferUsageFlags::UNIFORM_BUFFER,
                MemoryLocation::CpuToGpu,
            )?;
            scene_set.write_buffer_in(i, 8, &frame_constants)?;
            let readback = Buffer::new(
                &ctx,
                &format!("frame{i}.counters_readback"),
                // The ray counter, then the non-finite count.
                4 * (RAY_COUNTER_WORDS as u64 + 1),
                vk::BufferUsageFlags::TRANSFER_DST,
                MemoryLocation::GpuToCpu,
            )?;
            buffers.push((frame_constants, readback));
        }
        let lights = LightBuffers::new(&ctx, scene.lights.clone())?;
        lights.write_set(&scene_set)?;
        // What the settings can refuse (brute force over its limit, an image too large for the
        // device) is built first; the slots free their command buffers and fences when dropped.
        let parts = Self::build(&ctx, &scene, &scene_set, &lights.set, &settings, None)?;
        let mut slots = Vec::with_capacity(FRAME_SLOTS);
        for (i, (frame_constants, readback)) in buffers.into_iter().enumerate() {
            let timer = GpuTimer::new(&ctx, 32)?;
            let (cmd, fence) = ctx.command_buffer_and_fence(&format!("frame{i}"), false)?;
            slots.push(FrameSlot { ctx: ctx.clone(), cmd, fence, timer, readback, frame_constants, pending: None });
        }
        let log = FrameLog { pixels: parts.targets.pixels() as f64, ..Default::default() };
        Ok(Self {
            settings,
            scene,
            scene_set,
            lights,
            extra_lights: Vec::new(),
            parts,
            slots,
            next_slot: 0,
            camera: None,
            state: FrameState::default(),
            nonfinite_total: 0,
            log,
            last_stats: FrameStats::default(),
            capture_buffer: None,
            last_plan: None,
            debug_poison: match poison.as_deref() {
                Some("vpl_shade") => crate::gpu_types::POISON_VPL_SHADE,
                Some("ray_carry") => crate::gpu_types::POISON_RAY_CARRY,
                Some("vpl_presample") => crate::gpu_types::POISON_VPL_PRESAMPLE,
                Some("regir_build") => crate::gpu_types::POISON_REGIR_BUILD,
                _ => 0,
            },
            debug_hang: debug_hang(&ctx, poison.as_deref())?,
            ctx,
        })
    }

    /// Builds what `settings` decide: frame targets, passes, the VPL set and the VPL shading
    /// setup. From `old`, keeps the targets when the size is unchanged and the VPL set when the
    /// photon settings, the texture variant and the need for VPLs are unchanged.
    fn build(
        ctx: &Arc<Context>,
        scene: &SceneGpu,
        scene_set: &DescriptorSet,
        lights: &LightSet,
        settings: &RenderSettings,
        old: Option<(&mut Parts, &RenderSettings, bool)>,
    ) -> Result<Parts> {
        let textured = scene.textured && settings.textures;
        let layout = scene_set.layout;
        // What can be kept from the old parts: the targets (same size) and the VPL set (same
        // photon settings, texture variant and need for VPLs). The VPL set is moved over only once
        // everything else is built, so a failure leaves the old parts whole.
        let (old_targets, mut old_photons) = match old {
            Some((p, s, same_lights)) => {
                let same_grid = (s.width, s.height, s.workgroup) == (settings.width, settings.height, settings.workgroup);
                let same_vpls = same_lights
                    && p.textured == textured
                    && s.needs_vpls() == settings.needs_vpls()
                    && s.photon_settings() == settings.photon_settings();
                (same_grid.then(|| p.targets.clone()), same_vpls.then_some(&mut p.photons))
            }
            None => (None, None),
        };
        if settings.mode == Mode::Bruteforce {
            // Checked before anything is built; the VPL count is the kept set's or the target one.
            let vpls = match old_photons.as_ref().and_then(|p| p.as_ref()) {
                Some((_, stats)) => PhotonEmitPass::vpl_count(stats) as u64,
                None => settings.vpls_direct as u64 + if settings.gi { settings.vpls_indirect as u64 } else { 0 },
            };
            check_bruteforce_pairs(settings, vpls)?;
        }
        let targets = match old_targets {
            Some(t) => t,
            None => Rc::new(FrameTargets::new(ctx, settings.width, settings.height, settings.workgroup).context("allocating frame targets")?),
        };
        let mut passes = Passes::new(ctx, layout, textured, settings.mode == Mode::Pt, &targets).context("creating passes")?;
        let info = &scene.info;
        if textured {
            log::info!(
                "textures: {} ({:.1} MiB of texels, {} textured materials): gbuffer, pathtrace, photon_emit and vpl_compensate use their textured variants",
                scene.texture_count,
                scene.texel_bytes as f64 / (1 << 20) as f64,
                info.textured_materials
            );
        } else if info.textured_materials > 0 {
            log::info!(
                "textures: off: {} textured materials use their base colour factor; untextured shader variants",
                info.textured_materials
            );
        } else {
            log::info!("textures: none in the scene: untextured shader variants, no texture bindings");
        }
        let new_photons = match &old_photons {
            Some(_) => None,
            None if settings.needs_vpls() => {
                let pass = PhotonEmitPass::new(ctx, layout, textured, lights, settings.photon_settings())
                    .context("creating the photon pass")?;
                let stats = pass.run(scene_set.set).context("tracing photons")?;
                log::info!(
                    "photon_emit: ran once before frame 0 (static scene): {} direct + {} indirect VPLs from {} paths in {:.1} GPU ms",
                    stats.direct_vpls,
                    stats.indirect_vpls,
                    stats.paths,
                    stats.gpu_ms
                );
                Some((pass, stats))
            }
            None => {
                log::info!("photon_emit: skipped (mode {} uses no VPLs and none are dumped)", settings.mode.name());
                None
            }
        };
        let vpl = {
            let photons = match &old_photons {
                Some(kept) => kept.as_ref(),
                None => new_photons.as_ref(),
            };
            if settings.view == View::Vpls {
                let (pass, stats) = photons.expect("--view vpls builds the VPL set");
                passes.vpl_view = Some(Self::vpl_view(ctx, settings, scene, layout, &targets, pass, stats)?);
            }
            match (photons, settings.mode.uses_vpls()) {
                (Some((pass, stats)), true) => {
                    Some(Self::vpl_setup(ctx, settings, scene, layout, &targets, &mut passes, pass, stats)?)
                }
                _ => None,
            }
        };
        let photons = match old_photons.as_mut() {
            Some(kept) => kept.take(),
            None => new_photons,
        };
        Ok(Parts { textured, targets, passes, photons, vpl })
    }

    /// The warning a `--vpl-radius` large against the scene deserves (None below 2 % of its
    /// diagonal): each sphere is splatted over at most VPL_VIEW_MAX_FOOTPRINT pixels either side of
    /// its centre, and one that holds the camera is skipped (vpl_view.comp). Said once by the
    /// caller (a headless run keeps it in the summary; the window at its start), not at every
    /// rebuild of the pass.
    pub fn vpl_radius_warning(settings: &RenderSettings, scene: &SceneGpu) -> Option<String> {
        let (lo, hi) = scene.info.bounds;
        let diagonal = (hi - lo).length().max(1e-6);
        let radius = settings.vpl_radius.filter(|&r| r > 0.02 * diagonal)?;
        Some(format!(
            "--vpl-radius {radius} is {:.1}% of the scene's diagonal: spheres that hold the camera are not drawn, and a \
             sphere wider than {} px on screen is cut to a square",
            100.0 * radius / diagonal,
            2 * crate::passes::vpl_view::VPL_VIEW_MAX_FOOTPRINT + 1
        ))
    }

    /// Switches to `settings` without re-uploading the scene: rebuilds the passes, the frame
    /// targets when the size changed and the VPL set when its settings changed (see
    /// [`Renderer::build`]). The accumulation, the ReSTIR history and the log restart. Waits for the
    /// device to be idle first (a caller's own work on the renderer's buffers included).
    pub fn apply_settings(&mut self, settings: RenderSettings) -> Result<()> {
        let settings = settings_for_device(&self.ctx, settings)?;
        // A change of nothing, or of the exposure alone (applied by tonemap to the accumulated
        // mean), keeps the passes and the accumulation: dragging the exposure slider restarted it.
        if (RenderSettings { exposure: self.settings.exposure, ..settings.clone() }) == self.settings {
            self.settings.exposure = settings.exposure;
            return Ok(());
        }
        self.complete_all()?;
        // Waiting for idle before pipelines and buffers in use are replaced.
        self.ctx.wait_idle()?;
        let parts = Self::build(
            &self.ctx,
            &self.scene,
            &self.scene_set,
            &self.lights.set,
            &settings,
            Some((&mut self.parts, &self.settings, true)),
        )?;
        self.parts = parts;
        self.settings = settings;
        self.state = FrameState::default();
        self.log = FrameLog { pixels: self.parts.targets.pixels() as f64, ..Default::default() };
        // The last frame's statistics were the old settings' (the overlay showed the old mode's
        // passes under the new mode's name, for as long as the loop stayed frozen).
        self.last_stats = FrameStats::default();
        Ok(())
    }

    /// The `--view vpls` pass over the photon pass's VPLs (spheres of `--vpl-radius`, default 0.25%
    /// of the scene's diagonal).
    fn vpl_view(
        ctx: &Arc<Context>,
        settings: &RenderSettings,
        scene: &SceneGpu,
        scene_layout: vk::DescriptorSetLayout,
        targets: &FrameTargets,
        pass: &PhotonEmitPass,
        stats: &PhotonStats,
    ) -> Result<VplViewPass> {
        let (lo, hi) = scene.info.bounds;
        let radius = settings.vpl_radius.unwrap_or(0.0025 * (hi - lo).length().max(1e-6));
        VplViewPass::new(ctx, scene_layout, targets, &pass.vpls, PhotonEmitPass::vpl_count(stats), radius)
    }

    /// The VPL modes' shared inputs and passes: alias table over the VPL powers (power source
    /// only), Yuksel radius, reservoirs, and only the passes the mode uses.
    #[allow(clippy::too_many_arguments)]
    fn vpl_setup(
        ctx: &Arc<Context>,
        settings: &RenderSettings,
        scene_gpu: &SceneGpu,
        scene_layout: ash::vk::DescriptorSetLayout,
        targets: &FrameTargets,
        passes: &mut Passes,
        photon_pass: &PhotonEmitPass,
        stats: &PhotonStats,
    ) -> Result<VplSetup> {
        let vpl_count = PhotonEmitPass::vpl_count(stats);
        let layout = scene_layout;
        let mode = settings.mode;
        if mode == Mode::Bruteforce {
            check_bruteforce_pairs(settings, vpl_count as u64)?;
        }
        let mut need_power = mode.uses_reservoirs() && settings.candidate_source == CandidateSource::Power && mode != Mode::Uniform;
        // Alias entries are read as RG32UI texels (shaders/common/texel_records.glsl).
        let alias_buffer = |name: &str, bytes: &[u8]| {
            crate::vk::Buffer::with_texel_data(ctx, name, bytes, crate::passes::ALIAS_TEXELS, ash::vk::BufferUsageFlags::STORAGE_BUFFER)
        };
        let mut total_vpl_lum = 0.0f64;
        let mut notes = Vec::new();
        let weights: Option<Vec<f64>> = if need_power {
            let vpls = photon_pass.read_vpls(stats)?;
            let weights: Vec<f64> = vpls.iter().map(|v| crate::lights::luminance(Vec3::from(v.flux)).max(0.0) as f64).collect();
            total_vpl_lum = weights.iter().sum();
            Some(weights)
        } else {
            None
        };
        if need_power && total_vpl_lum <= 0.0 {
            // No VPL carries power (an empty set, a scene without emitters): the image is black
            // whatever the candidates, as with the uniform source, which draws them instead (the
            // power pdf would divide by the zero total).
            log::warn!("{POWERLESS_VPLS}");
            notes.push(POWERLESS_VPLS.to_string());
            need_power = false;
        }
        let alias = if let Some(weights) = weights.filter(|_| need_power) {
            let table = crate::lights::alias_table(&weights);
            alias_buffer("restir_initial.vpl_alias", bytemuck::cast_slice(&table))?
        } else {
            // The binding is declared by the shader but not read without the power source.
            alias_buffer("restir_initial.vpl_alias(unused)", &[0u8; 8])?
        };
        let mut flags = 0;
        let (yuksel_radius, yuksel_radius_source) = match settings.attenuation {
            Attenuation::InverseSquare => (None, None),
            Attenuation::Yuksel => match settings.yuksel_radius {
                Some(r) => (Some(r), Some("--yuksel-radius".to_string())),
                None => {
                    let multiple = settings.yuksel_spacings.unwrap_or(crate::settings::DEFAULT_RADIUS_SPACINGS);
                    let area = scene_gpu.info.surface_area;
                    let spacing =
                        (area / (std::f64::consts::PI * vpl_count.max(1) as f64)).sqrt() as f32;
                    let r = multiple * spacing;
                    let given = if settings.yuksel_spacings.is_some() { "" } else { " (the default)" };
                    anyhow::ensure!(
                        r <= crate::settings::MAX_YUKSEL_RADIUS,
                        "--yuksel-spacings {multiple}{given}: gives a Yuksel radius of {r:e} ({multiple} × the mean VPL spacing {spacing:e}, \
                         from {}'s surface area {area:e} over {vpl_count} VPLs), over {:e} scene units; check the scene's size, \
                         or give --yuksel-radius",
                        scene_gpu.info.path.display(),
                        crate::settings::MAX_YUKSEL_RADIUS
                    );
                    let r = if r > 0.0 && r.is_finite() { r } else { 1e-3 };
                    let text = crate::settings::radius_rule_text(multiple, settings.yuksel_knn);
                    match settings.yuksel_knn {
                        None => (Some(r), Some(text)),
                        Some(k) => {
                            // Each VPL's own r² goes into its record; the global r stays the
                            // fallback of VPLs without a local spacing (coincident ones).
                            let median = photon_pass.set_knn_radii(stats, k, multiple, r)?;
                            // (set_knn_radii said it on stderr when it searched.)
                            notes.extend(crate::passes::photon_emit::knn_set_warning(k, vpl_count as usize));
                            flags |= VPL_FLAG_PER_VPL_RADIUS;
                            (Some(median), Some(text))
                        }
                    }
                }
            },
        };
        let r = &settings.restir;
        let unbiased = mode == Mode::Restir && r.bias == Bias::Unbiased;
        if mode == Mode::Restir && r.initial_visibility() {
            flags |= VPL_FLAG_INITIAL_VISIBILITY;
        }
        if unbiased {
            flags |= VPL_FLAG_UNBIASED;
        }
        let kind_mask = match settings.view {
            View::Direct => KIND_MASK_DIRECT,
            View::Indirect => KIND_MASK_INDIRECT,
            _ => KIND_MASK_DIRECT | KIND_MASK_INDIRECT,
        };
        let params = GpuVplParams {
            vpl_count,
            attenuation: match settings.attenuation {
                Attenuation::InverseSquare => ATTENUATION_INVERSE_SQUARE,
                Attenuation::Yuksel => ATTENUATION_YUKSEL,
            },
            yuksel_r2: yuksel_radius.map(|r| r * r).unwrap_or(0.0),
            kind_mask,
            candidates: settings.initial_candidates(),
            source: if need_power { 1 } else { 0 },
            total_vpl_lum: total_vpl_lum as f32,
            flags,
        };
        let inputs = VplInputs { vpls: &photon_pass.vpls, alias: &alias };
        let mut reservoirs = None;
        let mut no_tiles: Option<Buffer> = None;
        let mut no_grid: Option<(Buffer, Buffer)> = None;
        if mode == Mode::Bruteforce {
            passes.vpl.bruteforce = Some(VplBruteforcePass::new(ctx, layout, targets, &inputs)?);
        } else if mode.uses_reservoirs() {
            let res = Reservoirs::new(ctx, targets.pixels())?;
            if settings.presamples() {
                passes.vpl.presample = Some(VplPresamplePass::new(ctx, layout, &inputs, targets.width, targets.height)?);
            }
            let tiles = match &passes.vpl.presample {
                Some(p) => &p.tiles,
                // The binding is declared by the shader but not read without presampling.
                None => &*no_tiles.insert(VplPresamplePass::tiles_buffer(ctx, "vpl_presample.tiles(unused)", 32)?),
            };
            if settings.uses_grid() {
                passes.vpl.regir = Some(RegirBuildPass::new(ctx, layout, &inputs, scene_gpu.info.bounds, &settings.grid)?);
            } else {
                // The bindings are declared by the shaders but not read without a grid.
                no_grid = Some((
                    VplPresamplePass::tiles_buffer(ctx, "regir.entries(unused)", 48)?,
                    crate::vk::Buffer::with_data(ctx, "regir.cells(unused)", &[0u8; 16], ash::vk::BufferUsageFlags::STORAGE_BUFFER)?,
                ));
            }
            let grid = match (&passes.vpl.regir, &no_grid) {
                (Some(p), _) => GridBuffers { entries: &p.entries, cells: &p.cells, built: true },
                (None, Some((entries, cells))) => GridBuffers { entries, cells, built: false },
                (None, None) => unreachable!("made above"),
            };
            passes.vpl.initial = Some(RestirInitialPass::new(ctx, layout, targets, &inputs, &res, tiles, &grid)?);
            passes.vpl.shade = Some(VplShadePass::new(ctx, layout, targets, &inputs, &res)?);
            if mode == Mode::Restir {
                if r.temporal {
                    passes.vpl.temporal = Some(RestirTemporalPass::new(ctx, layout, targets, &inputs, &res)?);
                    if settings.fuse_passes == Some(true) {
                        passes.vpl.initial_temporal = Some(RestirInitialTemporalPass::new(ctx, layout, targets, &inputs, &res, tiles, &grid)?);
                    }
                    if r.boiling_filter > 0.0 {
                        passes.vpl.boiling = Some(RestirBoilingPass::new(ctx, layout, &res)?);
                    }
                }
                if r.spatial_passes > 0 && r.spatial_neighbours > 0 {
                    passes.vpl.spatial = Some(RestirSpatialPass::new(ctx, layout, targets, &inputs, &res, params.flags)?);
                    if settings.fuse_passes == Some(true) {
                        passes.vpl.spatial_shade = Some(RestirSpatialShadePass::new(ctx, layout, targets, &inputs, &res, params.flags)?);
                    }
                }
            }
            reservoirs = Some(res);
        }
        let compensate_bits = if settings.compensate { compensate_first_hop(settings.view, settings.gi) } else { 0 };
        if compensate_bits != 0 {
            let textured = scene_gpu.textured && settings.textures;
            passes.vpl.compensate = Some(VplCompensatePass::new(ctx, layout, textured, targets, &inputs)?);
        }
        let compensate = (GpuVplParams { candidates: settings.candidates.max(1), ..params }, compensate_bits);
        log::info!(
            "vpl: {vpl_count} VPLs, attenuation {:?}{}, {} candidate(s) from the {} source",
            settings.attenuation,
            yuksel_radius.map(|r| format!(" (r = {r:.4})")).unwrap_or_default(),
            params.candidates,
            if need_power { "power" } else { "uniform" }
        );
        Ok(VplSetup {
            vpl_count,
            yuksel_radius,
            yuksel_radius_source,
            params,
            compensate,
            _alias: alias,
            _no_tiles: no_tiles,
            _no_grid: no_grid,
            reservoirs,
            notes,
        })
    }

    /// What the next frame will run. `preview`: also run the tonemap pass; `capture`: the frame's
    /// pass outputs are captured, so no fused pass hides one; `displayed_alone`: the frame is shown
    /// alone (the camera moved, or `--progressive off`).
    fn plan(&self, preview: bool, capture: bool, displayed_alone: bool) -> FramePlan {
        let s = &self.settings;
        let st = &self.state;
        let mode = s.mode;
        let vpls_view = s.view == View::Vpls;
        // A shading pass runs when its mode wants it, unless --view vpls replaces the shading.
        let shading = |runs: bool, why_not: &'static str| {
            if vpls_view {
                Step::Skip("--view vpls draws the VPLs instead")
            } else if runs {
                Step::Run
            } else {
                Step::Skip(why_not)
            }
        };
        let restir_step = |enabled: bool, why_not: &'static str| {
            shading(mode == Mode::Restir && enabled, if mode == Mode::Restir { why_not } else { "mode is not restir" })
        };
        let r = &s.restir;
        // Temporal reuse runs this frame (restir_temporal, or fused in restir_initial_temporal).
        let temporal_runs = r.temporal && st.history_valid;
        let gbuffer = if s.aa {
            Step::Run
        } else if st.gbuffer_valid {
            Step::Skip("camera still and no --aa: primary hits traced once")
        } else {
            Step::Run
        };
        // A frame displayed alone whose temporal reuse has history: its own error hardly depends
        // on the candidates and neighbours there, so it draws fewer (--moving-candidates,
        // --moving-neighbours; docs/performance.md, "Frames displayed alone").
        let moving_sampling = s.moving_sampling();
        let moving = mode == Mode::Restir && temporal_runs && displayed_alone && moving_sampling != (s.candidates, r.spatial_neighbours);
        let vpl = match &self.parts.vpl {
            Some(v) => {
                let mut params = v.params;
                let mut restir = *r;
                if moving {
                    (params.candidates, restir.spatial_neighbours) = moving_sampling;
                }
                if gbuffer != Step::Run {
                    // The previous frame's surfaces are this frame's: reuse needs no reprojection
                    // and its MIS weights reduce to confidence weights.
                    params.flags |= VPL_FLAG_SAME_DOMAIN;
                }
                VplFrame {
                    params,
                    restir,
                    moving,
                    // A pixel without history is a first frame's: the still count (docs/performance.md,
                    // "Frames displayed alone").
                    neighbours_without_history: r.spatial_neighbours,
                    // Its candidates too, decided per pixel in the initial pass.
                    candidates_without_history: v.params.candidates,
                    view: s.view,
                    current: st.current_reservoirs,
                    compensate_params: v.compensate.0,
                    compensate_first_hop: v.compensate.1,
                }
            }
            None => VplFrame::default(),
        };
        let mut plan = FramePlan {
            gbuffer,
            pathtrace: shading(mode == Mode::Pt, "mode is not pt"),
            vpl_bruteforce: shading(mode == Mode::Bruteforce, "mode is not bruteforce"),
            vpl_presample: if s.presamples() {
                shading(true, "")
            } else if mode.uses_reservoirs() {
                shading(false, if mode == Mode::Uniform { "uniform sampling reads one VPL per pixel" } else { "--presample off" })
            } else {
                shading(false, "mode picks no VPLs per pixel")
            },
            regir_build: if s.uses_grid() {
                shading(true, "")
            } else if matches!(mode, Mode::Ris | Mode::Restir) {
                shading(false, "--grid-candidates 0")
            } else {
                shading(false, "mode draws no RIS candidates")
            },
            restir_initial: shading(mode.uses_reservoirs(), "mode picks no VPLs per pixel"),
            restir_temporal: restir_step(
                temporal_runs,
                if !r.temporal { "--temporal off" } else if st.frame_index == 0 { "no history before the first frame" } else { "no history: settings or lights changed" },
            ),
            restir_initial_temporal: Step::Skip("decided by fuse()"),
            // On the temporal pass's output: only where temporal reuse runs (fused or not).
            restir_boiling: restir_step(
                r.boiling_filter > 0.0 && temporal_runs,
                if r.boiling_filter <= 0.0 {
                    "--boiling-filter 0"
                } else if !r.temporal {
                    "--temporal off"
                } else {
                    "restir_temporal does not run this frame"
                },
            ),
            restir_spatial: restir_step(
                r.spatial_passes > 0 && r.spatial_neighbours > 0,
                "--spatial-passes 0 or --spatial-neighbours 0",
            ),
            restir_spatial_shade: Step::Skip("decided by fuse()"),
            vpl_shade: shading(mode.uses_reservoirs(), "mode picks no VPLs per pixel"),
            vpl_compensate: match self.parts.vpl.as_ref().map(|v| v.compensate.1) {
                _ if !s.compensate => Step::Skip("no --compensate"),
                Some(bits) if bits != 0 => shading(true, ""),
                Some(_) => Step::Skip("the view shows no light to compensate"),
                None => Step::Skip("mode has no VPLs"),
            },
            vpl_view: match self.settings.view {
                View::Vpls => Step::Run,
                _ => Step::Skip("no --view vpls"),
            },
            accumulate: Step::Run,
            tonemap: if preview { Step::Run } else { Step::Skip("no preview needed this frame") },
            reset_accumulation: st.accumulated == 0,
            vpl,
        };
        self.fuse(&mut plan, capture);
        plan
    }

    /// `--fuse-passes`: where both passes of a pair run this frame, one fused dispatch replaces
    /// them (same functions, same random streams), unless the frame's pass outputs are captured
    /// (`--dump-passes`, `--check-finite`, the window's F4) or the view reads vpl_shade's reservoir
    /// views.
    fn fuse(&self, plan: &mut FramePlan, capture: bool) {
        let vpl = &self.parts.passes.vpl;
        let apart = if self.settings.fuse_passes != Some(true) {
            Some("--fuse-passes off")
        } else if capture {
            Some(crate::passes::CAPTURED_APART)
        } else {
            None
        };
        // The reasons in the order a reader asks them: could the pair run at all, does it run this
        // frame, and only then why it runs apart.
        let restir = self.settings.mode == Mode::Restir;
        plan.restir_initial_temporal = match apart {
            _ if !restir || !plan.vpl.restir.temporal => Step::Skip("mode is not restir or --temporal off"),
            _ if plan.restir_temporal != Step::Run => Step::Skip("restir_temporal does not run this frame"),
            Some(why) => Step::Skip(why),
            None if vpl.initial_temporal.is_none() => Step::Skip("mode is not restir or --temporal off"),
            None => Step::Run,
        };
        if plan.restir_initial_temporal == Step::Run {
            plan.restir_initial = Step::Skip("fused into restir_initial_temporal");
            plan.restir_temporal = Step::Skip("fused into restir_initial_temporal");
        }
        plan.restir_spatial_shade = match apart {
            _ if !restir || plan.vpl.restir.spatial_passes == 0 => Step::Skip("mode is not restir or no spatial reuse"),
            _ if plan.restir_spatial != Step::Run || plan.vpl_shade != Step::Run => Step::Skip("restir_spatial or vpl_shade does not run this frame"),
            _ if plan.vpl.view.shows_reservoirs() => Step::Skip("vpl_shade draws the reservoir view"),
            Some(why) => Step::Skip(why),
            None if vpl.spatial_shade.is_none() => Step::Skip("mode is not restir or no spatial reuse"),
            None => Step::Run,
        };
        if plan.restir_spatial_shade == Step::Run {
            plan.vpl_shade = Step::Skip("fused into restir_spatial_shade");
            if plan.vpl.restir.spatial_passes == 1 {
                plan.restir_spatial = Step::Skip("fused into restir_spatial_shade");
            }
        }
    }

    /// `prev`: the previous frame's camera; `halves`: (this frame's, the previous frame's) half of
    /// the G-buffer ping-pong.
    fn frame_constants(&self, camera: &Camera, prev: &Camera, halves: (u32, u32)) -> GpuFrame {
        let s = &self.settings;
        GpuFrame {
            camera_position: camera.position.to_array(),
            tan_half_fov: (camera.yfov * 0.5).tan(),
            camera_right: camera.right.to_array(),
            aspect: s.width as f32 / s.height as f32,
            camera_up: camera.up.to_array(),
            frame_index: self.state.frame_index,
            camera_forward: camera.forward.to_array(),
            seed: s.seed,
            width: s.width,
            height: s.height,
            max_bounces: s.max_bounces,
            flags: if s.aa { FRAME_AA } else { 0 },
            light_count: self.lights.set.lights.len() as u32,
            instance_count: self.scene.instance_count as u32,
            total_light_power: self.lights.set.total_power_lum as f32,
            exposure: 2f32.powf(s.exposure),
            debug_poison: self.debug_poison,
            accumulated_frames: self.state.accumulated + 1,
            surface_offset: halves.0 * self.parts.targets.surface_half_records,
            prev_surface_offset: halves.1 * self.parts.targets.surface_half_records,
            prev_camera_position: prev.position.to_array(),
            prev_tan_half_fov: (prev.yfov * 0.5).tan(),
            prev_camera_right: prev.right.to_array(),
            prev_camera_up: prev.up.to_array(),
            prev_camera_forward: prev.forward.to_array(),
            ..Default::default()
        }
    }

    /// Renders one frame seen from `camera` and adds it to the accumulation; waits for it and
    /// returns its statistics (also kept in [`Renderer::log`]). `preview`: also tonemap it for
    /// [`Renderer::read_preview`]. A camera other than the last frame's restarts the accumulation
    /// and traces the G-buffer again.
    pub fn render_frame(&mut self, camera: &Camera, preview: bool) -> Result<FrameStats> {
        self.complete_all()?;
        self.submit_frame(camera, preview)?;
        self.complete_all()?;
        Ok(self.last_stats.clone())
    }

    /// Records and submits one frame without waiting for it, so that up to [`FRAME_SLOTS`] frames
    /// are in flight (the window's loop). The slot it uses may still hold an older frame: that one
    /// is completed first, and its statistics are returned.
    pub fn submit_frame(&mut self, camera: &Camera, preview: bool) -> Result<Option<FrameStats>> {
        Ok(self.submit(camera, preview, false)?.0)
    }

    /// Renders one frame as [`Renderer::render_frame`] does and also returns every pass's output
    /// as it stood right after that pass ran (copied out between the passes: `--dump-passes`,
    /// `--check-finite`). A frame rendered without it records no copies.
    pub fn render_frame_captured(&mut self, camera: &Camera, preview: bool) -> Result<(FrameStats, Vec<Captured>)> {
        self.complete_all()?;
        let (_, metas) = self.submit(camera, preview, true)?;
        self.complete_all()?;
        let buffer = self.capture_buffer.as_ref().context("the capture buffer exists after a captured frame")?;
        let mut captured = Vec::with_capacity(metas.len());
        for m in metas {
            captured.push(Captured {
                position: m.position,
                pass: m.pass,
                repeat: m.repeat,
                buffer: m.buffer,
                kind: m.kind,
                origin: self.scene.info.origin,
                shape: m.shape,
                bytes: buffer.read(m.offset as usize, m.size as usize)?,
            });
        }
        Ok((self.last_stats.clone(), captured))
    }

    /// Records and submits one frame; with `capture`, copies each pass's output aside after it.
    fn submit(&mut self, camera: &Camera, preview: bool, capture: bool) -> Result<(Option<FrameStats>, Vec<CaptureMeta>)> {
        // A NaN camera would render a black frame without a word; every camera maker keeps its
        // basis finite (Camera::look_at), so this is a last check, not the usual message.
        anyhow::ensure!(camera.is_finite(), "the camera ({}) is not finite: {camera:?}", camera.source);
        self.ctx.ensure_not_hung()?;
        let start = Instant::now();
        let i = self.next_slot;
        let completed = if self.slots[i].pending.is_some() { Some(self.complete_frame(i)?) } else { None };
        let prev_camera = self.camera.unwrap_or(*camera);
        let moved = !prev_camera.same_view(camera);
        if moved {
            // A new view: new primary hits and a new accumulation; the ReSTIR history is kept and
            // reprojected.
            self.state.gbuffer_valid = false;
            self.state.accumulated = 0;
        }
        if !self.settings.progressive || self.settings.view.shows_reservoirs() {
            // Every image is this frame alone (the reservoir and motion views show one frame's
            // reservoirs and reprojection, not a mean over frames).
            self.state.accumulated = 0;
        }
        self.camera = Some(*camera);
        let plan = self.plan(preview, capture, moved || !self.settings.progressive);
        // --verbose: the first frame's passes and the last one's (a still camera's later frames
        // skip the G-buffer and run the temporal pass).
        if self.state.frame_index == 0 || u64::from(self.state.frame_index) + 1 == u64::from(self.settings.frames) {
            log::info!("frame {} passes:\n{}", self.state.frame_index, plan.describe());
        }
        // A traced G-buffer goes to the other half: the previous frame's surfaces stay readable.
        let half = self.state.surface_half;
        let halves = if plan.gbuffer == Step::Run { (1 - half, half) } else { (half, half) };
        let constants = self.frame_constants(camera, &prev_camera, halves);
        if capture {
            // Room for what this frame's dispatches write (the same rule as the copies below).
            let bytes: u64 = plan
                .dispatches()
                .into_iter()
                .filter_map(|d| dispatch_output(d, &self.parts, plan.vpl.current, halves.0))
                .map(|o| o.size())
                .sum();
            let need = bytes.max(4);
            if self.capture_buffer.as_ref().is_none_or(|b| b.size < need) {
                self.capture_buffer = Some(Buffer::new(&self.ctx, "capture.pass_outputs", need, vk::BufferUsageFlags::TRANSFER_DST, MemoryLocation::GpuToCpu)?);
            }
        }
        let ctx = self.ctx.clone();
        let d = &ctx.device;
        let slot = &mut self.slots[i];
        slot.frame_constants.write(0, bytemuck::bytes_of(&constants))?;
        // SAFETY: the slot's previous submission has completed (its fence was waited on).
        unsafe {
            d.reset_command_buffer(slot.cmd, vk::CommandBufferResetFlags::empty())?;
            d.begin_command_buffer(
                slot.cmd,
                &vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
            )?;
        }
        slot.timer.reset(slot.cmd);
        // Orders this frame after the previous one's last reads of the shared targets, and makes
        // what earlier submissions wrote (uploads, acceleration structures, photons) visible.
        crate::vk::pipeline::submission_start_barrier(&ctx, slot.cmd);
        let mut metas = Vec::new();
        let hang = self.debug_hang;
        if capture {
            let parts = &self.parts;
            let current = plan.vpl.current;
            let cap = self.capture_buffer.as_ref().expect("allocated before recording");
            let mut used = 0u64;
            let mut hook = |cmd: vk::CommandBuffer, d: crate::passes::Dispatch| {
                if let Some(o) = dispatch_output(d, parts, current, halves.0) {
                    let size = o.size();
                    assert!(used + size <= cap.size, "the capture buffer was sized from the same dispatches");
                    let region = [vk::BufferCopy::default().src_offset(o.offset).dst_offset(used).size(size)];
                    // SAFETY: both buffers are alive; the pass's barrier precedes the copy and the one
                    // below orders the passes after it (they may overwrite the source).
                    unsafe { ctx.device.cmd_copy_buffer(cmd, o.src.raw, cap.raw, &region) };
                    crate::vk::pipeline::compute_barrier(&ctx, cmd);
                    metas.push(CaptureMeta { position: metas.len(), pass: d.name, repeat: d.repeat, buffer: o.buffer, kind: o.kind, shape: o.shape, offset: used, size });
                    used += size;
                }
                record_debug_hang(&ctx, cmd, d, hang);
            };
            self.parts.passes.record_frame(&ctx, slot.cmd, &mut slot.timer, self.scene_set.variants[i], &self.parts.targets, &plan, &mut hook);
        } else {
            let mut hook = |cmd, d| record_debug_hang(&ctx, cmd, d, hang);
            self.parts.passes.record_frame(&ctx, slot.cmd, &mut slot.timer, self.scene_set.variants[i], &self.parts.targets, &plan, &mut hook);
        }
        let counters_size = 4 * RAY_COUNTER_WORDS as u64;
        // SAFETY: buffers alive; the barrier after the last pass orders the copies after it.
        unsafe {
            d.cmd_copy_buffer(
                slot.cmd,
                self.parts.targets.ray_counter.raw,
                slot.readback.raw,
                &[vk::BufferCopy::default().size(counters_size)],
            );
            d.cmd_copy_buffer(
                slot.cmd,
                self.parts.targets.stats.raw,
                slot.readback.raw,
                &[vk::BufferCopy::default().size(4).dst_offset(counters_size)],
            );
            // The host reads the counters (and any capture) after the fence.
            crate::vk::pipeline::host_read_barrier(&ctx, slot.cmd);
            d.end_command_buffer(slot.cmd)?;
            let cmds = [slot.cmd];
            let submit = [vk::SubmitInfo::default().command_buffers(&cmds)];
            d.reset_fences(&[slot.fence])?;
            d.queue_submit(ctx.queue, &submit, slot.fence).context("vkQueueSubmit (frame)")?;
        }
        slot.pending = Some(PendingFrame {
            start,
            gbuffer_ran: plan.gbuffer == Step::Run,
            reset: plan.reset_accumulation,
            frame: self.state.frame_index,
            moving: plan.vpl.moving,
        });
        let st = &mut self.state;
        if plan.gbuffer == Step::Run {
            st.gbuffer_valid = true;
        }
        st.surface_half = halves.0;
        if plan.shades_reservoirs() {
            // The final reservoirs become the next frame's history; the other buffer is free.
            st.current_reservoirs = 1 - plan.vpl.final_buffer(plan.spatial_passes());
            st.history_valid = true;
        }
        st.accumulated += 1;
        st.frame_index += 1;
        self.next_slot = (i + 1) % FRAME_SLOTS;
        self.last_plan = Some(plan);
        Ok((completed, metas))
    }

    /// The pass list of the last frame recorded: which passes ran, which were skipped and why.
    pub fn last_plan(&self) -> Option<&FramePlan> {
        self.last_plan.as_ref()
    }

    /// Waits for the frame in slot `i` and logs its statistics.
    fn complete_frame(&mut self, i: usize) -> Result<FrameStats> {
        let slot = &mut self.slots[i];
        let PendingFrame { start, gbuffer_ran, reset, frame, moving } = slot.pending.context("no frame is pending in this slot")?;
        let timer = &slot.timer;
        self.ctx.wait_fence(slot.fence, &|| format!("frame {frame}"), &|| timer.progress())?;
        // Only now is the slot free (a wait that failed leaves it pending: the frame may run on).
        slot.pending = None;
        let dispatch_ms = slot.timer.collect()?;
        let n_slots = RAY_SLOTS.len();
        let counters: Vec<u32> = bytemuck::pod_collect_to_vec(&slot.readback.read(0, 4 * (RAY_COUNTER_WORDS + 1))?);
        // The GPU's count covers the accumulation so far: what this frame added is the difference
        // to the last frame's (frames complete in submission order), or all of it after a reset.
        let count = counters[RAY_COUNTER_WORDS] as u64;
        // In 32 bits, as the GPU counts: across a wrap of its counter the difference is still
        // right (a frame adds at most one per pixel, far below 2^32).
        let added = if reset { count } else { u64::from((count as u32).wrapping_sub(self.state.nonfinite_samples as u32)) };
        self.nonfinite_total += added;
        self.ctx.add_nonfinite_samples(added);
        self.state.nonfinite_samples = count;
        let primary = if gbuffer_ran { self.parts.targets.pixels() as u64 } else { 0 };
        let mut rays_by_pass = vec![("gbuffer", primary)];
        for (slot, (name, _)) in crate::passes::RAY_SLOT_NAMES.iter().enumerate() {
            let count = u64::from(counters[slot]) | u64::from(counters[n_slots + slot]) << 32;
            if count > 0 {
                match rays_by_pass.iter_mut().find(|(n, _)| n == name) {
                    Some(entry) => entry.1 += count,
                    None => rays_by_pass.push((name, count)),
                }
            }
        }
        let rays = rays_by_pass.iter().map(|r| r.1).sum();
        let stats = FrameStats { dispatch_ms, rays, rays_by_pass, wall_ms: start.elapsed().as_secs_f64() * 1e3, moving };
        self.log.push(&stats);
        self.last_stats = stats.clone();
        Ok(stats)
    }

    /// The statistics of the last frame completed.
    pub fn last_stats(&self) -> &FrameStats {
        &self.last_stats
    }

    /// Completes every frame still in flight (their statistics go to the log).
    pub fn complete_all(&mut self) -> Result<()> {
        for k in 0..FRAME_SLOTS {
            let i = (self.next_slot + k) % FRAME_SLOTS;
            if self.slots[i].pending.is_some() {
                self.complete_frame(i)?;
            }
        }
        Ok(())
    }

    /// Point lights in addition to the scene's (the window's L key). The lights change, so the VPL
    /// set is traced again (the photon pass re-runs) and the passes over it are rebuilt; the scene
    /// is not touched. The accumulation and the ReSTIR history restart.
    pub fn set_extra_lights(&mut self, extra: Vec<PointEmitter>) -> Result<()> {
        self.complete_all()?;
        // Waiting for idle before the light buffers in use are replaced.
        self.ctx.wait_idle()?;
        let set = LightSet::new(&self.scene.emitters, &extra);
        // The loader's limit, checked again: each spawned light adds a quarter of the scene's
        // power (past the limit the 32-bit fluxes overflow and the image goes black).
        // (Every channel's finiteness apart: f64::max passes over a NaN, and folded through it
        // a NaN channel was lost to any later one.)
        let most = set.total_power.iter().copied().fold(0.0, f64::max);
        anyhow::ensure!(
            set.total_power.iter().all(|p| p.is_finite()) && most <= crate::scene::MAX_LIGHT_POWER,
            "the lights would emit {most:.3e} W together, more than the {:.0e} W the renderer's 32-bit fluxes hold",
            crate::scene::MAX_LIGHT_POWER
        );
        let lights = LightBuffers::new(&self.ctx, set)?;
        // The photon pass reads the lights through set 0: point it at the new ones first, and back
        // at the old ones if the rebuild fails.
        lights.write_set(&self.scene_set)?;
        let settings = self.settings.clone();
        let built = Self::build(
            &self.ctx,
            &self.scene,
            &self.scene_set,
            &lights.set,
            &settings,
            Some((&mut self.parts, &self.settings, false)),
        );
        let parts = match built {
            Ok(p) => p,
            Err(e) => {
                self.lights.write_set(&self.scene_set)?;
                return Err(e);
            }
        };
        self.lights = lights;
        self.parts = parts;
        self.extra_lights = extra;
        self.state = FrameState::default();
        Ok(())
    }

    /// The point lights added to the scene's.
    pub fn extra_lights(&self) -> &[PointEmitter] {
        &self.extra_lights
    }

    /// The lights this renderer draws: the scene's and the added ones.
    pub fn lights(&self) -> &LightSet {
        &self.lights.set
    }

    /// Traces the VPL set again (the photon pass only; `bench --photons` times it) and rebuilds
    /// what depends on it: the VPL passes, their alias table and radius. The accumulation and the
    /// ReSTIR history restart. Returns the new photon statistics. After an error the VPL passes
    /// may be half rebuilt: drop the renderer (its one caller, `bench --photons`, does).
    pub fn retrace_photons(&mut self) -> Result<PhotonStats> {
        self.complete_all()?;
        let Some((pass, stats)) = &mut self.parts.photons else {
            anyhow::bail!("this run has no VPL set to retrace (mode pt without --dump-vpls or --view vpls)");
        };
        *stats = pass.run(self.scene_set.set).context("tracing photons")?;
        let (pass, stats) = self.parts.photons.as_ref().expect("checked above");
        if self.parts.passes.vpl_view.is_some() {
            self.parts.passes.vpl_view = Some(Self::vpl_view(&self.ctx, &self.settings, &self.scene, self.scene_set.layout, &self.parts.targets, pass, stats)?);
        }
        if self.parts.vpl.is_some() {
            self.parts.passes.vpl = Default::default();
            self.parts.vpl = Some(Self::vpl_setup(
                &self.ctx,
                &self.settings,
                &self.scene,
                self.scene_set.layout,
                &self.parts.targets,
                &mut self.parts.passes,
                pass,
                stats,
            )?);
        }
        self.state.history_valid = false;
        self.state.accumulated = 0;
        Ok(stats.clone())
    }

    /// Starts a new, independent accumulation with pixel seed `seed`: the VPL set, G-buffer and
    /// pipelines stay; the running mean, the ReSTIR history, the frame counter and the log restart.
    /// (The photon pass keeps the VPLs it traced with the original seed.)
    pub fn restart(&mut self, seed: u32) -> Result<()> {
        self.complete_all()?;
        self.settings.seed = seed;
        self.state = FrameState {
            gbuffer_valid: self.state.gbuffer_valid,
            surface_half: self.state.surface_half,
            ..Default::default()
        };
        self.log = FrameLog { pixels: self.log.pixels, ..Default::default() };
        Ok(())
    }

    /// Starts a new accumulation but keeps everything else: the frame counter (so random numbers
    /// continue), the ReSTIR history and the G-buffer. The log restarts too. Used after warm-up
    /// frames, so that ReSTIR is measured in its steady state.
    pub fn reset_accumulation(&mut self) -> Result<()> {
        self.complete_all()?;
        self.state.accumulated = 0;
        self.log = FrameLog { pixels: self.log.pixels, ..Default::default() };
        Ok(())
    }

    /// Makes the next frame frame number `index` of the random sequence (frame k uses the same
    /// random numbers in any run, so that references rendered in parts combine).
    pub fn set_frame_index(&mut self, index: u32) -> Result<()> {
        self.complete_all()?;
        self.state.frame_index = index;
        Ok(())
    }

    pub fn settings(&self) -> &RenderSettings {
        &self.settings
    }

    pub fn scene(&self) -> &SceneGpu {
        &self.scene
    }

    /// The camera a run starts from: the settings' `--eye/--target` if given, else the scene's
    /// (see [`Camera::initial`]).
    pub fn initial_camera(&self) -> Camera {
        Camera::initial(&self.scene.info, self.settings.camera.as_ref())
    }

    /// Whether this renderer draws with the textured shader variants (the scene was uploaded with
    /// textures and the settings keep them on).
    pub fn textured(&self) -> bool {
        self.parts.textured
    }

    /// The camera of the last frame, if one was rendered.
    pub fn camera(&self) -> Option<Camera> {
        self.camera
    }

    /// Frame times and rays since the log was last cleared.
    pub fn log(&self) -> &FrameLog {
        &self.log
    }

    /// Frames in the current accumulation.
    pub fn accumulated(&self) -> u32 {
        self.state.accumulated
    }

    /// Non-finite samples replaced by 0 in the current accumulation.
    pub fn nonfinite_samples(&self) -> u64 {
        self.state.nonfinite_samples
    }

    /// Non-finite samples replaced by 0 in every frame completed since the renderer was made
    /// (what a run reports: its camera may have moved, restarting the accumulation).
    pub fn nonfinite_samples_total(&self) -> u64 {
        self.nonfinite_total
    }

    pub fn pixels(&self) -> u32 {
        self.parts.targets.pixels()
    }

    /// The photon pass's statistics, when the run traced VPLs.
    pub fn photon_stats(&self) -> Option<&PhotonStats> {
        self.parts.photons.as_ref().map(|p| &p.1)
    }

    /// How many of the ReGIR grid's cells the last frame built (None: no grid). Waits for the GPU.
    pub fn grid_cells_built(&mut self) -> Result<Option<u32>> {
        self.complete_all()?;
        let Some(pass) = &self.parts.passes.vpl.regir else { return Ok(None) };
        let cells = read_back_records::<[u32; 4]>(&self.ctx, &pass.cells, (pass.params.cells as usize).pow(3))?;
        // The last frame rendered was frame_index - 1, whose build stamped frame_index.
        let stamp = self.state.frame_index;
        Ok(Some(cells.iter().filter(|c| stamp > 0 && c[1] == stamp).count() as u32))
    }

    /// The warnings of this renderer's set-up that the run's summary keeps (each also went to
    /// stderr when it arose): settings the device or the VPL set made moot.
    pub fn setup_warnings(&self) -> Vec<String> {
        let mut out = Vec::new();
        out.extend(tracing_workgroup_warning(&self.ctx, &self.settings));
        if let Some(v) = &self.parts.vpl {
            out.extend(v.notes.iter().cloned());
        }
        out
    }

    /// The VPL setup as summary.json reports it.
    pub fn vpl_summary(&self) -> Option<VplSummary> {
        self.parts.vpl.as_ref().map(|v| VplSummary {
            vpl_count: v.vpl_count,
            yuksel_radius: v.yuksel_radius,
            yuksel_radius_source: v.yuksel_radius_source.clone(),
            candidates: if self.settings.mode.uses_reservoirs() { v.params.candidates } else { 0 },
            candidate_source: if v.params.source == 1 { "power" } else { "uniform" },
            presample: self.parts.passes.vpl.presample.is_some(),
            grid: self.parts.passes.vpl.regir.is_some().then_some(self.settings.grid),
            grid_cells_built: None,
            initial_visibility: v.params.flags & VPL_FLAG_INITIAL_VISIBILITY != 0,
            unbiased_reuse: v.params.flags & VPL_FLAG_UNBIASED != 0,
            spatial_radius_px: self
                .parts
                .passes
                .vpl
                .spatial
                .is_some()
                .then(|| self.settings.restir.spatial_radius_px(self.settings.width)),
            moving_sampling: (self.settings.mode == Mode::Restir && self.settings.restir.temporal).then(|| {
                let (candidates, neighbours) = self.settings.moving_sampling();
                [candidates, neighbours]
            }),
            moving_frames: self.log.moving_frames,
        })
    }

    /// The final reservoirs of the last frame (VPL modes with reservoirs).
    pub fn read_reservoirs(&self) -> Result<Option<Vec<crate::gpu_types::GpuReservoir>>> {
        let Some(res) = self.parts.vpl.as_ref().and_then(|v| v.reservoirs.as_ref()) else {
            return Ok(None);
        };
        let last = 1 - self.state.current_reservoirs;
        Ok(Some(read_back_records(&self.ctx, res.buffer(last), self.parts.targets.pixels() as usize)?))
    }

    /// The VPL set (direct first, then indirect), when the run has one.
    pub fn read_vpls(&self) -> Result<Option<Vec<crate::gpu_types::GpuVpl>>> {
        self.parts.photons.as_ref().map(|(pass, stats)| pass.read_vpls(stats)).transpose()
    }

    /// The running mean, row 0 at the top, RGB.
    pub fn read_mean(&self) -> Result<Vec<[f32; 3]>> {
        let v: Vec<[f32; 4]> = read_back_records(&self.ctx, &self.parts.targets.mean, self.parts.targets.pixels() as usize)?;
        Ok(v.iter().map(|p| [p[0], p[1], p[2]]).collect())
    }

    /// The last frame's own estimate per pixel (before accumulation), row 0 at the top, RGB.
    pub fn read_frame_samples(&self) -> Result<Vec<[f32; 3]>> {
        let v: Vec<[f32; 4]> = read_back_records(&self.ctx, &self.parts.targets.samples, self.parts.targets.pixels() as usize)?;
        Ok(v.iter().map(|p| [p[0], p[1], p[2]]).collect())
    }

    /// Per-pixel sample variance of the accumulated frames (unbiased, n − 1), RGB; saturated at
    /// `f32::MAX` where it does not fit a float ([`sample_variance`]).
    pub fn read_variance(&self) -> Result<Vec<[f32; 3]>> {
        let n = self.state.accumulated as f64;
        let pixels = self.parts.targets.pixels() as usize;
        let d: Vec<[f32; 4]> = read_back_records(&self.ctx, &self.parts.targets.accum_deviations, pixels)?;
        Ok(d.iter().map(|p| [0, 1, 2].map(|ch| sample_variance(p[ch], n))).collect())
    }

    /// The buffer the tonemap pass writes the preview to (RGBA8, sRGB-encoded, row 0 at the top,
    /// `width × height` texels). A caller that copies from it on the same queue after
    /// [`Renderer::submit_frame`] must put a compute-write → transfer-read barrier first.
    pub fn preview_buffer(&self) -> &Buffer {
        &self.parts.targets.preview
    }

    /// The tonemapped preview (RGBA8, sRGB), valid after a frame rendered with `preview = true`.
    pub fn read_preview(&self) -> Result<Vec<u8>> {
        let mut bytes = read_back(&self.ctx, &self.parts.targets.preview)?;
        bytes.truncate(self.parts.targets.pixels() as usize * 4);
        Ok(bytes)
    }
}

impl Drop for Renderer {
    fn drop(&mut self) {
        if self.ctx.is_hung() {
            return; // a frame may still be executing: its fence and command buffer stay
        }
        // SAFETY: wait for idle; the slots' command buffers and fences are freed as they drop.
        unsafe {
            let _ = self.ctx.device.device_wait_idle();
            if let Some((_, event)) = self.debug_hang {
                self.ctx.device.destroy_event(event, None);
            }
        }
    }
}

impl Drop for FrameSlot {
    fn drop(&mut self) {
        if self.ctx.is_hung() {
            return; // a frame may still be executing: its fence and command buffer stay
        }
        // SAFETY: no pending work uses them: Renderer's Drop waited for idle, and a slot dropped by
        // a failing `Renderer::new` was never submitted.
        unsafe {
            self.ctx.device.destroy_fence(self.fence, None);
            self.ctx.device.free_command_buffers(self.ctx.command_pool, &[self.cmd]);
        }
    }
}

/// The unbiased sample variance of n accumulated samples from the accumulation's mean squared
/// deviation (Welford's M2 / n), as the accumulate pass keeps it in floats. Deviations beyond
/// ~1.8e19 (a scene with absurdly bright lights) overflow it to +Inf on the GPU; the variance is
/// then at least `f32::MAX` and reported as that, so no Inf or NaN reaches a variance image or a
/// reference's noise estimate.
pub fn sample_variance(mean_squared_deviation: f32, n: f64) -> f32 {
    if !(n > 1.0) {
        return 0.0;
    }
    let var = mean_squared_deviation as f64 * n / (n - 1.0);
    if var.is_nan() || var >= f32::MAX as f64 {
        f32::MAX
    } else {
        var.max(0.0) as f32
    }
}

#[cfg(test)]
mod tests {
    use super::sample_variance;

    #[test]
    fn sample_variance_is_exact_and_saturates_instead_of_overflowing() {
        // Samples 1, 2, 3, 4: mean 2.5, M2 / n = 5/4, unbiased variance 5/3.
        let v = sample_variance(1.25, 4.0);
        assert!((v - 5.0 / 3.0).abs() < 1e-6, "{v}");
        assert_eq!(sample_variance(7.0, 1.0), 0.0, "one sample has no variance estimate");
        // Deviations of 1e20 overflow the float M2 on the GPU (1e40 > f32::MAX).
        assert_eq!(sample_variance(f32::INFINITY, 2.0), f32::MAX);
        assert_eq!(sample_variance(f32::NAN, 2.0), f32::MAX);
        // Rounding never makes it negative.
        assert_eq!(sample_variance(-1e-9, 2.0), 0.0);
    }
}
