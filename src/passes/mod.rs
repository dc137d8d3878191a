//! The frame, pass by pass. Each pass is `src/passes/<name>.rs` + `shaders/passes/<name>.comp`, owns
//! its pipeline and set-1 bindings, and is recorded inside a debug label and GPU timestamp scope of
//! the same name. What the two files must agree on is the pass's [`PassDesc`] (`<Name>Pass::DESC`),
//! checked against the SPIR-V by tests/layout.rs. [`Passes::record_frame`] is the whole frame on
//! one screen.

pub mod accumulate;
pub mod desc;
pub mod gbuffer;
pub mod pathtrace;
pub mod photon_emit;
pub mod regir_build;
pub mod restir_boiling;
pub mod restir_initial;
pub mod restir_initial_temporal;
pub mod restir_spatial;
pub mod restir_spatial_shade;
pub mod restir_temporal;
pub mod tonemap;
pub mod vpl_bruteforce;
pub mod vpl_compensate;
pub mod vpl_presample;
pub mod vpl_shade;
pub mod vpl_view;

use std::sync::Arc;

use anyhow::Result;
use ash::vk;
use gpu_allocator::MemoryLocation;

use crate::gpu_types::{GpuGridParams, GpuReservoir, GpuSurfaceTexels, GpuVpl, GpuVplCandidate, GpuVplParams, GBUFFER_CHUNKS, GLSL_CONSTANTS};
use crate::settings::{RestirSettings, View};
use crate::vk::pipeline::compute_barrier;
use crate::vk::{Buffer, Context, GpuTimer, TexelFormat};

pub use accumulate::AccumulatePass;
pub use desc::PassDesc;
pub use gbuffer::GbufferPass;
pub use pathtrace::PathtracePass;
pub use photon_emit::{PhotonEmitPass, PhotonStats};
pub use regir_build::RegirBuildPass;
pub use restir_boiling::RestirBoilingPass;
pub use restir_initial::RestirInitialPass;
pub use restir_initial_temporal::RestirInitialTemporalPass;
pub use restir_spatial::RestirSpatialPass;
pub use restir_spatial_shade::RestirSpatialShadePass;
pub use restir_temporal::RestirTemporalPass;
pub use tonemap::TonemapPass;
pub use vpl_bruteforce::VplBruteforcePass;
pub use vpl_compensate::VplCompensatePass;
pub use vpl_presample::VplPresamplePass;
pub use vpl_shade::VplShadePass;
pub use vpl_view::VplViewPass;

/// Every pass, for the checks of each desc against its SPIR-V (tests/layout.rs).
pub const ALL_PASSES: &[&PassDesc] = &[
    &GbufferPass::DESC,
    &PathtracePass::DESC,
    &PhotonEmitPass::DESC,
    &VplBruteforcePass::DESC,
    &VplPresamplePass::DESC,
    &RegirBuildPass::DESC,
    &RestirInitialPass::DESC,
    &RestirTemporalPass::DESC,
    &RestirInitialTemporalPass::DESC,
    &RestirBoilingPass::DESC,
    &RestirSpatialPass::DESC,
    &RestirSpatialShadePass::DESC,
    &VplShadePass::DESC,
    &VplCompensatePass::DESC,
    &VplViewPass::DESC,
    &AccumulatePass::DESC,
    &TonemapPass::DESC,
];

/// [`ALL_PASSES`] as a list.
pub fn all_pass_descs() -> Vec<&'static PassDesc> {
    ALL_PASSES.to_vec()
}

/// Slots of `FrameTargets::ray_counter`: (the pass that traced them, the slot's `RAYS_*` constant
/// in shaders/common/types.glsl, whose value is the index here). Every count is 64-bit: slot i's
/// high word is at `RAYS_HIGH + i` (shaders/common/ray_count.glsl carries into it). A frame may
/// trace more than 2^32 rays in one pass: brute force (2e10 pixel × VPL pairs allowed), ReSTIR's
/// spatial passes at the largest image (8.4M pixels × 32 neighbours × 2 rays × 8 passes), the
/// initial pass with visible targets (1024 candidates a pixel).
pub const RAY_SLOT_NAMES: [(&str, &str); 9] = [
    (PathtracePass::NAME, "RAYS_PATHTRACE"),
    (RestirInitialPass::NAME, "RAYS_INITIAL"),
    (RestirTemporalPass::NAME, "RAYS_TEMPORAL"),
    (RestirSpatialPass::NAME, "RAYS_SPATIAL"),
    (VplShadePass::NAME, "RAYS_SHADE"),
    (VplBruteforcePass::NAME, "RAYS_BRUTEFORCE"),
    (VplCompensatePass::NAME, "RAYS_COMPENSATE"),
    (RestirInitialTemporalPass::NAME, "RAYS_INITIAL_TEMPORAL"),
    (RestirSpatialShadePass::NAME, "RAYS_SPATIAL_SHADE"),
];

/// Words of `FrameTargets::ray_counter`: a low and a high word per slot (the high words from
/// `RAYS_HIGH`, [`RAY_SLOT_NAMES`]' length).
pub const RAY_COUNTER_WORDS: usize = 2 * RAY_SLOT_NAMES.len();

/// The pass of each slot of `FrameTargets::ray_counter` (from [`RAY_SLOT_NAMES`]).
pub const RAY_SLOTS: [&str; RAY_SLOT_NAMES.len()] = {
    let mut out = [""; RAY_SLOT_NAMES.len()];
    let mut i = 0;
    while i < out.len() {
        out[i] = RAY_SLOT_NAMES[i].0;
        i += 1;
    }
    out
};

/// Every `const uint` shaders/common/types.glsl must declare: [`GLSL_CONSTANTS`] and the ray-counter
/// slots.
pub fn glsl_constants() -> Vec<(&'static str, u32)> {
    let slots = RAY_SLOT_NAMES.iter().enumerate().map(|(i, (_, glsl))| (*glsl, i as u32));
    let high = std::iter::once(("RAYS_HIGH", RAY_SLOT_NAMES.len() as u32));
    GLSL_CONSTANTS.iter().copied().chain(slots).chain(high).collect()
}

/// The texel format through which passes read records at per-lane addresses (surfaces, VPLs,
/// reservoirs, presampled candidates; set 0's vertices, materials, instances and lights):
/// shaders/common/texel_records.glsl decodes them, and says why they are not read as storage
/// buffers. Every such record is a whole number of these texels.
pub const RECORD_TEXELS: TexelFormat = TexelFormat { format: vk::Format::R32G32B32A32_UINT, bytes: 16 };
/// Alias-table entries (`AliasEntry`, 8 bytes) are read one RG32UI texel each, index lists
/// (`u32`) one R32UI texel each.
pub const ALIAS_TEXELS: TexelFormat = TexelFormat { format: vk::Format::R32G32_UINT, bytes: 8 };
pub const WORD_TEXELS: TexelFormat = TexelFormat { format: vk::Format::R32_UINT, bytes: 4 };
const _: () = assert!(
    std::mem::size_of::<GpuSurfaceTexels>().is_multiple_of(16)
        && std::mem::size_of::<GpuVpl>().is_multiple_of(16)
        && std::mem::size_of::<GpuReservoir>().is_multiple_of(16)
        && std::mem::size_of::<GpuVplCandidate>().is_multiple_of(16)
        && std::mem::size_of::<crate::gpu_types::GpuVertex>().is_multiple_of(16)
        && std::mem::size_of::<crate::gpu_types::GpuMaterial>().is_multiple_of(16)
        && std::mem::size_of::<crate::gpu_types::GpuInstance>() == 9 * 16
        && std::mem::size_of::<crate::gpu_types::GpuLight>().is_multiple_of(16)
        && std::mem::size_of::<crate::gpu_types::GpuAliasEntry>() == 8
);

/// Per-pixel buffers shared between passes.
pub struct FrameTargets {
    pub width: u32,
    pub height: u32,
    /// How the per-pixel passes tile the image: their workgroup (x, y) (`--workgroup`).
    pub workgroup: [u32; 2],
    /// `GpuSurfaceTexels` per pixel (gbuffer output), twice: a ping-pong of this frame's and the
    /// previous frame's G-buffer, each half `surface_half_records` records from its start
    /// (`GpuFrame::surface_offset`, `prev_surface_offset`), for reprojection.
    pub surfaces: Buffer,
    /// Records per G-buffer half: the pixel count rounded up to a multiple of 16, so that the
    /// `GBUFFER_CHUNKS` storage-buffer ranges `gbuffer` writes through start 256-byte aligned.
    pub surface_half_records: u32,
    /// This frame's radiance estimate per pixel (vec4).
    pub samples: Buffer,
    /// The accumulation's state (vec4 each): its running mean, that mean's Neumaier compensation,
    /// and Welford's mean squared deviation (M2 / n).
    pub accum_running_mean: Buffer,
    pub accum_compensation: Buffer,
    pub accum_deviations: Buffer,
    /// Running mean (vec4): the accumulated image.
    pub mean: Buffer,
    /// RGBA8 sRGB preview.
    pub preview: Buffer,
    /// Rays traced this frame by the sampling passes (reset every frame).
    pub ray_counter: Buffer,
    /// Whole-run statistics: non-finite sample count.
    pub stats: Buffer,
}

impl FrameTargets {
    /// Refuses an image of more pixels than the device's buffer limits let the per-pixel buffers
    /// hold (`bench --rays` checks its own size with it before it measures anything).
    pub fn check_size(ctx: &Context, width: u32, height: u32) -> Result<()> {
        let limits = &ctx.properties.limits;
        let n = width as u64 * height as u64;
        // Per-pixel buffers must fit one descriptor: the G-buffer's two halves (128 bytes a pixel)
        // are texels (2^27 of them on lavapipe: 16.8M pixels), the others storage buffers of up to
        // 16 bytes a pixel (lavapipe's 128 MiB maxStorageBufferRange: 8.4M pixels).
        // The G-buffer is written through GBUFFER_CHUNKS storage-buffer ranges of equal size, so a
        // range holds 2 * 64 / 8 = 16 bytes a pixel, as the other per-pixel buffers do; the pixel
        // count is rounded down to the 16-pixel granule a half is rounded up to.
        let granule = 16u64;
        let record = std::mem::size_of::<GpuSurfaceTexels>() as u64;
        let max_pixels = (u64::from(limits.max_texel_buffer_elements) * RECORD_TEXELS.bytes / (2 * record))
            .min(u64::from(limits.max_storage_buffer_range) * u64::from(GBUFFER_CHUNKS) / (2 * record))
            .min(u64::from(limits.max_storage_buffer_range) / 16)
            / granule
            * granule;
        anyhow::ensure!(
            n <= max_pixels,
            "--width {width} --height {height}: {n} pixels, more than this device's buffer limits allow (at most {max_pixels} \
             pixels: maxTexelBufferElements {} for the G-buffer, maxStorageBufferRange {} bytes for 16 bytes a pixel)",
            limits.max_texel_buffer_elements,
            limits.max_storage_buffer_range
        );
        Ok(())
    }

    /// `workgroup`: checked against the device's compute limits here, before any pass is built.
    pub fn new(ctx: &Arc<Context>, width: u32, height: u32, workgroup: [u32; 2]) -> Result<Self> {
        let limits = &ctx.properties.limits;
        let [x, y] = workgroup;
        anyhow::ensure!(
            x <= limits.max_compute_work_group_size[0]
                && y <= limits.max_compute_work_group_size[1]
                && x * y <= limits.max_compute_work_group_invocations,
            "--workgroup {x}x{y}: this device allows at most {}x{} and {} invocations per workgroup",
            limits.max_compute_work_group_size[0],
            limits.max_compute_work_group_size[1],
            limits.max_compute_work_group_invocations
        );
        Self::check_size(ctx, width, height)?;
        let n = width as u64 * height as u64;
        let granule = 16u64;
        let record = std::mem::size_of::<GpuSurfaceTexels>() as u64;
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER
            | vk::BufferUsageFlags::TRANSFER_SRC
            | vk::BufferUsageFlags::TRANSFER_DST;
        let make = |name: &str, bytes: u64| Buffer::new(ctx, name, bytes, storage, MemoryLocation::GpuOnly);
        let texel = vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER;
        let half_records = n.div_ceil(granule) * granule;
        Ok(Self {
            width,
            height,
            workgroup,
            surfaces: Buffer::new(ctx, "gbuffer.surfaces", 2 * half_records * record, storage | texel, MemoryLocation::GpuOnly)?
                .with_texel_view(RECORD_TEXELS)?,
            surface_half_records: u32::try_from(half_records).expect("bounded by max_pixels"),
            samples: make("frame.samples", n * 16)?,
            accum_running_mean: make("accumulate.running_mean", n * 16)?,
            accum_compensation: make("accumulate.compensation", n * 16)?,
            accum_deviations: make("accumulate.deviations", n * 16)?,
            mean: make("accumulate.mean", n * 16)?,
            preview: make("tonemap.preview", n * 4)?,
            ray_counter: make("frame.ray_counter", 4 * RAY_COUNTER_WORDS as u64)?,
            stats: make("frame.stats", 16)?,
        })
    }

    pub fn pixels(&self) -> u32 {
        self.width * self.height
    }

    /// Records per storage-buffer range `gbuffer` writes the G-buffer through: an equal share of
    /// both halves (a multiple of 4 records, so each range starts 256-byte aligned).
    pub fn surface_chunk_records(&self) -> u32 {
        2 * self.surface_half_records / GBUFFER_CHUNKS
    }
}

/// The VPL set as the VPL passes read it.
pub struct VplInputs<'a> {
    /// `GpuVpl`s, direct then indirect.
    pub vpls: &'a Buffer,
    /// Alias table over lum(Φ_i) (a placeholder when the power source is not used).
    pub alias: &'a Buffer,
}

/// The ReGIR grid's buffers as `restir_initial` binds them (`regir_build`'s, or placeholders when
/// there is no grid).
pub struct GridBuffers<'a> {
    pub entries: &'a Buffer,
    pub cells: &'a Buffer,
    /// A real grid: the passes use their `grid` variants (the default ones hold no grid code).
    pub built: bool,
}

/// The two reservoir buffers the ReSTIR passes ping-pong between. Which one holds what is decided
/// per frame in [`FramePlan`]: `current` receives the initial reservoirs, the other one holds the
/// previous frame's final reservoirs (the temporal history).
pub struct Reservoirs {
    pub a: Buffer,
    pub b: Buffer,
}

impl Reservoirs {
    pub fn new(ctx: &Arc<Context>, pixels: u32) -> Result<Self> {
        let bytes = pixels as u64 * std::mem::size_of::<GpuReservoir>() as u64;
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC;
        let make = |name: &str| {
            Buffer::new(ctx, name, bytes, usage, MemoryLocation::GpuOnly)?.with_texel_view(RECORD_TEXELS)
        };
        Ok(Self { a: make("reservoirs_a")?, b: make("reservoirs_b")? })
    }

    /// 0: `reservoirs_a`, 1: `reservoirs_b`.
    pub fn buffer(&self, index: usize) -> &Buffer {
        if index == 0 {
            &self.a
        } else {
            &self.b
        }
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
    pub vpl_bruteforce: Step,
    pub vpl_presample: Step,
    pub regir_build: Step,
    pub restir_initial: Step,
    pub restir_temporal: Step,
    /// `restir_initial` + `restir_temporal` in one dispatch (then both of those skip).
    pub restir_initial_temporal: Step,
    /// The boiling filter on the temporal pass's output (`--boiling-filter`).
    pub restir_boiling: Step,
    /// Runs `spatial_passes - 1` times when `restir_spatial_shade` runs the last one.
    pub restir_spatial: Step,
    /// The last spatial pass + `vpl_shade` in one dispatch (then `vpl_shade` skips).
    pub restir_spatial_shade: Step,
    pub vpl_shade: Step,
    pub vpl_compensate: Step,
    pub vpl_view: Step,
    pub accumulate: Step,
    pub tonemap: Step,
    /// Start a new accumulation (first frame, or after a change).
    pub reset_accumulation: bool,
    /// What the VPL passes need this frame.
    pub vpl: VplFrame,
}

/// Per-frame inputs of the VPL passes.
#[derive(Clone, Copy, Debug, Default)]
pub struct VplFrame {
    pub params: GpuVplParams,
    pub restir: RestirSettings,
    pub view: View,
    /// Reservoir buffer (0 = a, 1 = b) that receives this frame's initial reservoirs; the other
    /// holds the history.
    pub current: usize,
    /// `vpl_compensate`'s parameters (its own RIS candidate count at the hits it finds).
    pub compensate_params: GpuVplParams,
    /// `vpl_compensate`'s `COMPENSATE_*` bits for the view.
    pub compensate_first_hop: u32,
    /// `params.candidates` and `restir.spatial_neighbours` are those of a frame displayed alone
    /// (`RenderSettings::moving_sampling`), not the settings'.
    pub moving: bool,
    /// The spatial neighbours of a pixel whose reservoir has no temporal history: the settings'
    /// `spatial_neighbours` (in a moving frame more than `restir.spatial_neighbours`). Told apart
    /// by the reservoir's confidence (1), so in the first spatial pass only: later passes read
    /// merged confidences.
    pub neighbours_without_history: u32,
    /// The RIS candidates of a pixel without temporal history (the reprojection finds none, as
    /// `restir_temporal` decides): the settings' `candidates` in a moving frame (more than
    /// `params.candidates`), else `params.candidates`, so the initial pass makes no such test.
    pub candidates_without_history: u32,
}

impl VplFrame {
    /// The buffer holding the final reservoirs after `spatial_passes` ping-pong passes.
    pub fn final_buffer(&self, spatial_passes: u32) -> usize {
        self.current ^ (spatial_passes as usize & 1)
    }
}

/// Why a fused pair runs apart in a frame whose pass outputs are captured.
pub const CAPTURED_APART: &str = "pass outputs captured this frame";

impl FramePlan {
    /// Whether a pair that runs fused on the other frames runs apart in this one, because its
    /// pass outputs are captured.
    pub fn kept_apart_for_capture(&self) -> bool {
        [&self.restir_initial_temporal, &self.restir_spatial_shade].iter().any(|s| matches!(s, Step::Skip(why) if *why == CAPTURED_APART))
    }

    pub fn steps(&self) -> Vec<(&'static str, &Step)> {
        vec![
            (GbufferPass::NAME, &self.gbuffer),
            (PathtracePass::NAME, &self.pathtrace),
            (VplBruteforcePass::NAME, &self.vpl_bruteforce),
            (VplPresamplePass::NAME, &self.vpl_presample),
            (RegirBuildPass::NAME, &self.regir_build),
            (RestirInitialPass::NAME, &self.restir_initial),
            (RestirTemporalPass::NAME, &self.restir_temporal),
            (RestirInitialTemporalPass::NAME, &self.restir_initial_temporal),
            (RestirBoilingPass::NAME, &self.restir_boiling),
            (RestirSpatialPass::NAME, &self.restir_spatial),
            (RestirSpatialShadePass::NAME, &self.restir_spatial_shade),
            (VplShadePass::NAME, &self.vpl_shade),
            (VplCompensatePass::NAME, &self.vpl_compensate),
            (VplViewPass::NAME, &self.vpl_view),
            (AccumulatePass::NAME, &self.accumulate),
            (TonemapPass::NAME, &self.tonemap),
        ]
    }

    /// Whether the frame shades from the reservoirs (`vpl_shade`, or fused in
    /// `restir_spatial_shade`): then its final reservoirs are the next frame's history.
    pub fn shades_reservoirs(&self) -> bool {
        self.vpl_shade == Step::Run || self.restir_spatial_shade == Step::Run
    }

    /// Spatial merges this frame (`restir_spatial` dispatches, and `restir_spatial_shade`'s).
    pub fn spatial_passes(&self) -> u32 {
        if self.restir_spatial == Step::Run || self.restir_spatial_shade == Step::Run {
            self.vpl.restir.spatial_passes
        } else {
            0
        }
    }

    /// `restir_spatial` dispatches this frame: every spatial merge but the one
    /// `restir_spatial_shade` runs, when it runs.
    pub fn restir_spatial_dispatches(&self) -> u32 {
        self.spatial_passes() - u32::from(self.restir_spatial_shade == Step::Run)
    }

    /// Every dispatch this frame records, in order (`restir_spatial` once per dispatch).
    pub fn dispatches(&self) -> Vec<Dispatch> {
        self.steps()
            .into_iter()
            .filter(|(_, step)| **step == Step::Run)
            .flat_map(|(name, _)| {
                let times = if name == RestirSpatialPass::NAME { self.restir_spatial_dispatches() } else { 1 };
                (0..times).map(move |repeat| Dispatch { name, repeat })
            })
            .collect()
    }

    /// One line per pass: `run` or `skip (why)`.
    pub fn describe(&self) -> String {
        self.steps()
            .iter()
            .map(|(name, step)| match step {
                Step::Run if *name == RestirSpatialPass::NAME => {
                    format!("  {name:<24} run ×{}", self.restir_spatial_dispatches())
                }
                // (Uniform and RIS run it too: a uniform frame's one VPL per pixel is drawn here.)
                Step::Run if *name == RestirInitialPass::NAME || *name == RestirInitialTemporalPass::NAME => {
                    let n = self.vpl.params.candidates;
                    format!("  {name:<24} run ({n} candidate{} per pixel into its reservoir)", if n == 1 { "" } else { "s" })
                }
                Step::Run => format!("  {name:<24} run"),
                Step::Skip(why) => format!("  {name:<24} skip ({why})"),
            })
            .chain(self.vpl.moving.then(|| {
                format!(
                    "  (displayed alone with temporal history: {} candidates, {} neighbours, {} and {} for a pixel without history; --moving-candidates, --moving-neighbours)",
                    self.vpl.params.candidates,
                    self.vpl.restir.spatial_neighbours,
                    self.vpl.candidates_without_history,
                    self.vpl.neighbours_without_history
                )
            }))
            .collect::<Vec<_>>()
            .join("\n")
    }
}

/// The VPL passes a run needs (only those its mode uses are created).
#[derive(Default)]
pub struct VplPasses {
    pub bruteforce: Option<VplBruteforcePass>,
    /// Only with presampling (ris and restir, `--presample on`).
    pub presample: Option<VplPresamplePass>,
    /// Only with a ReGIR grid (ris and restir, `--grid-candidates` > 0).
    pub regir: Option<RegirBuildPass>,
    pub initial: Option<RestirInitialPass>,
    pub temporal: Option<RestirTemporalPass>,
    /// Only with `--fuse-passes on` (and a temporal pass).
    pub initial_temporal: Option<RestirInitialTemporalPass>,
    /// Only with `--boiling-filter S > 0` (and a temporal pass).
    pub boiling: Option<RestirBoilingPass>,
    pub spatial: Option<RestirSpatialPass>,
    /// Only with `--fuse-passes on` (and a spatial pass).
    pub spatial_shade: Option<RestirSpatialShadePass>,
    pub shade: Option<VplShadePass>,
    /// Only with `--compensate`.
    pub compensate: Option<VplCompensatePass>,
}

/// Every pass of the renderer.
pub struct Passes {
    pub gbuffer: GbufferPass,
    /// Only in mode pt.
    pub pathtrace: Option<PathtracePass>,
    pub accumulate: AccumulatePass,
    pub tonemap: TonemapPass,
    /// Only with `--view vpls`.
    pub vpl_view: Option<VplViewPass>,
    /// Only in the VPL modes.
    pub vpl: VplPasses,
}

impl Passes {
    /// `textured`: set 0 carries textures, so the passes that read albedo use `textured` variants.
    /// `path_traced`: mode pt, the only one that runs `pathtrace`.
    pub fn new(
        ctx: &Arc<Context>,
        scene_layout: vk::DescriptorSetLayout,
        textured: bool,
        path_traced: bool,
        targets: &FrameTargets,
    ) -> Result<Self> {
        Ok(Self {
            gbuffer: GbufferPass::new(ctx, scene_layout, textured, targets)?,
            pathtrace: path_traced.then(|| PathtracePass::new(ctx, scene_layout, textured, targets)).transpose()?,
            accumulate: AccumulatePass::new(ctx, scene_layout, targets)?,
            tonemap: TonemapPass::new(ctx, scene_layout, targets)?,
            vpl_view: None,
            vpl: VplPasses::default(),
        })
    }

    /// Records one frame: the pass order of the renderer, in one place. `after` is called after
    /// each dispatch that runs (and its barrier), for `--dump-passes` and `--check-finite` to copy
    /// what the pass wrote; a plain frame passes a no-op.
    #[allow(clippy::too_many_arguments)]
    pub fn record_frame(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        timer: &mut GpuTimer,
        scene_set: vk::DescriptorSet,
        targets: &FrameTargets,
        plan: &FramePlan,
        after: &mut dyn FnMut(vk::CommandBuffer, Dispatch),
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

        scoped(ctx, cmd, timer, after, 0, &plan.gbuffer, GbufferPass::NAME, |cmd| self.gbuffer.record(cmd, scene_set, w, h));
        if let Some(pass) = &self.pathtrace {
            scoped(ctx, cmd, timer, after, 0, &plan.pathtrace, PathtracePass::NAME, |cmd| pass.record(cmd, scene_set, w, h));
        }

        // VPL modes: brute force, or (presample ->) (ReGIR grid ->) initial RIS -> temporal (-> boiling filter) ->
        // spatial ×n -> shade; then compensate. With --fuse-passes: initial + temporal in one dispatch, and the last
        // spatial pass + shade in one (FramePlan says which run).
        let v = &plan.vpl;
        let p = &v.params;
        if let Some(pass) = &self.vpl.bruteforce {
            scoped(ctx, cmd, timer, after, 0, &plan.vpl_bruteforce, VplBruteforcePass::NAME, |cmd| pass.record(cmd, scene_set, p, w, h));
        }
        if let Some(pass) = &self.vpl.presample {
            scoped(ctx, cmd, timer, after, 0, &plan.vpl_presample, VplPresamplePass::NAME, |cmd| pass.record(cmd, scene_set, p));
        }
        let tiles = match (&self.vpl.presample, &plan.vpl_presample) {
            (Some(pass), Step::Run) => pass.tile_count,
            _ => 0,
        };
        if let Some(pass) = &self.vpl.regir {
            scoped(ctx, cmd, timer, after, 0, &plan.regir_build, RegirBuildPass::NAME, |cmd| pass.record(cmd, scene_set, p));
        }
        let grid = match (&self.vpl.regir, &plan.regir_build) {
            (Some(pass), Step::Run) => pass.params,
            _ => GpuGridParams::default(),
        };
        if let Some(pass) = &self.vpl.initial {
            scoped(ctx, cmd, timer, after, 0, &plan.restir_initial, RestirInitialPass::NAME, |cmd| {
                pass.record(cmd, scene_set, p, &grid, tiles, &v.restir, v.candidates_without_history, v.current, w, h)
            });
        }
        if let Some(pass) = &self.vpl.temporal {
            scoped(ctx, cmd, timer, after, 0, &plan.restir_temporal, RestirTemporalPass::NAME, |cmd| {
                pass.record(cmd, scene_set, p, &v.restir, v.current, w, h)
            });
        }
        if let Some(pass) = &self.vpl.initial_temporal {
            scoped(ctx, cmd, timer, after, 0, &plan.restir_initial_temporal, RestirInitialTemporalPass::NAME, |cmd| {
                pass.record(cmd, scene_set, p, &grid, tiles, &v.restir, v.candidates_without_history, v.current, w, h)
            });
        }
        if let Some(pass) = &self.vpl.boiling {
            scoped(ctx, cmd, timer, after, 0, &plan.restir_boiling, RestirBoilingPass::NAME, |cmd| {
                pass.record(cmd, scene_set, v.restir.boiling_filter, v.current, w, h)
            });
        }
        // Spatial merge j reads buffer current ^ (j & 1); the last one is fused with the shading
        // when restir_spatial_shade runs.
        let spatial = plan.spatial_passes();
        if let Some(pass) = &self.vpl.spatial {
            for j in 0..plan.restir_spatial_dispatches() {
                scoped(ctx, cmd, timer, after, j, &plan.restir_spatial, RestirSpatialPass::NAME, |cmd| {
                    pass.record(cmd, scene_set, p, &v.restir, v.neighbours_without_history, j, v.current ^ (j as usize & 1), w, h)
                });
            }
        }
        if let Some(pass) = &self.vpl.spatial_shade {
            scoped(ctx, cmd, timer, after, 0, &plan.restir_spatial_shade, RestirSpatialShadePass::NAME, |cmd| {
                let j = spatial - 1;
                pass.record(cmd, scene_set, p, &v.restir, v.neighbours_without_history, j, v.current ^ (j as usize & 1), w, h)
            });
        }
        if let Some(pass) = &self.vpl.shade {
            let reservoir = v.final_buffer(spatial);
            scoped(ctx, cmd, timer, after, 0, &plan.vpl_shade, VplShadePass::NAME, |cmd| {
                pass.record(cmd, scene_set, p, v.view, &v.restir, reservoir, w, h)
            });
        }
        if let Some(pass) = &self.vpl.compensate {
            scoped(ctx, cmd, timer, after, 0, &plan.vpl_compensate, VplCompensatePass::NAME, |cmd| {
                pass.record(cmd, scene_set, &v.compensate_params, v.compensate_first_hop, w, h)
            });
        }
        if let Some(view) = &self.vpl_view {
            scoped(ctx, cmd, timer, after, 0, &plan.vpl_view, VplViewPass::NAME, |cmd| view.record(cmd, scene_set, pixels));
        }
        scoped(ctx, cmd, timer, after, 0, &plan.accumulate, AccumulatePass::NAME, |cmd| {
            self.accumulate.record(cmd, scene_set, pixels, plan.reset_accumulation)
        });
        scoped(ctx, cmd, timer, after, 0, &plan.tonemap, TonemapPass::NAME, |cmd| self.tonemap.record(cmd, scene_set, pixels));
    }
}

/// The most storage buffers one pass's shader stage sees: set 0 of a textured scene plus the pass's
/// own set 1 (`gbuffer`'s chunk bindings). A device must allow at least this many per stage
/// (`crate::vk::context::REQUIRED_STORAGE_BUFFERS_PER_STAGE`, checked when devices are inspected).
pub fn storage_buffers_per_stage() -> u32 {
    let count = |t: &[crate::vk::Binding]| t.iter().filter(|b| b.kind == crate::vk::BindingKind::StorageBuffer).count() as u32;
    count(crate::scene_gpu::SCENE_BINDINGS_TEXTURED) + ALL_PASSES.iter().map(|d| count(d.bindings)).max().unwrap_or(0)
}

/// One dispatch of a pass as the frame records it: the pass's name and, for a pass dispatched
/// several times in a frame (`restir_spatial` ×P), which time (0-based).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Dispatch {
    pub name: &'static str,
    pub repeat: u32,
}

/// Runs `record` inside a label + timestamp scope named `name`, followed by a barrier and the
/// `after` hook, if the plan says the pass runs.
#[allow(clippy::too_many_arguments)]
fn scoped(
    ctx: &Context,
    cmd: vk::CommandBuffer,
    timer: &mut GpuTimer,
    after: &mut dyn FnMut(vk::CommandBuffer, Dispatch),
    repeat: u32,
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
    // After the barrier, which orders the pass before TRANSFER: the fill marks it finished.
    timer.breadcrumb(cmd);
    after(cmd, Dispatch { name, repeat });
}
