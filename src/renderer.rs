//! The renderer: scene on the GPU, frame targets, passes, and the per-frame submission.

use std::collections::BTreeMap;
use std::sync::Arc;

use anyhow::{Context as _, Result};
use ash::vk;
use glam::{Mat4, Vec3};

use crate::gpu_types::{
    GpuFrame, GpuVplParams, ATTENUATION_INVERSE_SQUARE, ATTENUATION_YUKSEL, FRAME_AA, KIND_MASK_DIRECT,
    KIND_MASK_INDIRECT, VPL_FLAG_INITIAL_VISIBILITY, VPL_FLAG_SAME_DOMAIN, VPL_FLAG_UNBIASED,
};
use crate::passes::{
    FramePlan, FrameTargets, Passes, PhotonEmitPass, PhotonStats, Reservoirs, RestirInitialPass, RestirSpatialPass,
    RestirTemporalPass, Step, VplBruteforcePass, VplFrame, VplInputs, VplShadePass, VplViewPass, RAY_SLOTS,
};
use crate::scene::Scene;
use crate::scene_gpu::SceneGpu;
use crate::settings::{Attenuation, Bias, CandidateSource, Mode, RenderSettings, View};
use crate::vk::buffer::read_back;
use crate::vk::{Context, GpuTimer};

/// The camera actually used: position and an orthonormal basis.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct CameraSetup {
    pub position: Vec3,
    pub forward: Vec3,
    pub right: Vec3,
    pub up: Vec3,
    pub yfov: f32,
    /// "scene camera 'name'", "command line" or "automatic (no camera in the scene)".
    pub source: &'static str,
}

impl CameraSetup {
    pub fn from_transform(t: Mat4, yfov: f32, source: &'static str) -> Self {
        let forward = (-t.z_axis.truncate()).normalize();
        let up0 = t.y_axis.truncate();
        let right = forward.cross(up0).normalize();
        let up = right.cross(forward);
        Self { position: t.w_axis.truncate(), forward, right, up, yfov, source }
    }

    pub fn look_at(eye: Vec3, target: Vec3, up: Vec3, yfov: f32, source: &'static str) -> Self {
        let forward = (target - eye).normalize();
        let right = forward.cross(up).normalize();
        let up = right.cross(forward);
        Self { position: eye, forward, right, up, yfov, source }
    }

    /// The camera for `scene` under `settings`: command line, else the scene's, else one that frames
    /// the scene's bounds from +z.
    pub fn choose(scene: &Scene, settings: &RenderSettings) -> Self {
        if let Some(c) = &settings.camera {
            return Self::look_at(c.eye, c.target, c.up, c.yfov_degrees.to_radians(), "command line");
        }
        if let Some(cam) = &scene.camera {
            return Self::from_transform(cam.transform, cam.yfov, "scene camera");
        }
        let (lo, hi) = scene.world_bounds();
        let centre = (lo + hi) * 0.5;
        let radius = ((hi - lo).length() * 0.5).max(1e-3);
        let yfov = 45f32.to_radians();
        let distance = radius / (yfov * 0.5).tan() * 1.1;
        Self::look_at(centre + Vec3::Z * distance, centre, Vec3::Y, yfov, "automatic (no camera in the scene)")
    }
}

/// Statistics of one rendered frame.
#[derive(Clone, Debug, Default)]
pub struct FrameStats {
    /// (pass, GPU ms) in recording order.
    pub pass_ms: Vec<(&'static str, f64)>,
    /// Rays traced this frame (primary + sampling passes).
    pub rays: u64,
    /// Rays per tracing pass this frame (primary rays under "gbuffer").
    pub rays_by_pass: Vec<(&'static str, u64)>,
    pub wall_ms: f64,
}

pub struct Renderer {
    pub settings: RenderSettings,
    pub camera: CameraSetup,
    pub scene: SceneGpu,
    pub targets: FrameTargets,
    passes: Passes,
    timer: GpuTimer,
    readback: crate::vk::Buffer,
    cmd: vk::CommandBuffer,
    fence: vk::Fence,
    /// Frames rendered since the accumulation started.
    pub accumulated: u32,
    /// Frames rendered in total (RNG frame index).
    pub frame_index: u32,
    gbuffer_valid: bool,
    /// Non-finite samples replaced by zero so far (counted by the accumulate pass).
    pub nonfinite_samples: u64,
    /// The VPL set, when the run needs one: traced once before the first frame (static scene).
    pub photons: Option<(PhotonEmitPass, PhotonStats)>,
    /// Per-pass GPU times of every frame so far (a pass dispatched several times in a frame, like
    /// restir_spatial, counts once with the sum).
    pub pass_times: BTreeMap<&'static str, Vec<f64>>,
    /// Rays per pass of every frame so far.
    pub pass_rays: BTreeMap<&'static str, Vec<u64>>,
    /// The VPL shading setup, in the VPL modes.
    pub vpl: Option<VplSetup>,
    /// Reservoir buffer that receives the next frame's initial reservoirs (0 = a, 1 = b).
    current_reservoirs: usize,
    /// The other reservoir buffer holds a previous frame's final reservoirs.
    history_valid: bool,
    pub ctx: Arc<Context>,
}

/// How the VPL modes shade: the VPL set's size and the parameters every VPL pass gets (reported
/// through [`VplSummary`]).
pub struct VplSetup {
    pub vpl_count: u32,
    /// Yuksel's r actually used (scene units), when the attenuation is Yuksel's.
    pub yuksel_radius: Option<f32>,
    /// Where the radius came from.
    pub yuksel_radius_source: Option<&'static str>,
    /// Σ lum(Φ_i) over the VPLs.
    pub total_vpl_lum: f64,
    pub params: GpuVplParams,
    _alias: crate::vk::Buffer,
    reservoirs: Option<Reservoirs>,
}

/// What summary.json reports about the VPL shading.
#[derive(Clone, Debug, serde::Serialize)]
pub struct VplSummary {
    pub vpl_count: u32,
    pub yuksel_radius: Option<f32>,
    pub yuksel_radius_source: Option<&'static str>,
    /// RIS candidates drawn by restir_initial (1 = uniform sampling).
    pub candidates: u32,
    /// "uniform" or "power".
    pub candidate_source: &'static str,
    /// Targets include visibility (initial sample shadow-tested).
    pub initial_visibility: bool,
    pub unbiased_reuse: bool,
}

/// Largest pixel × VPL product a brute-force frame accepts (~2 h on lavapipe, seconds on a GPU).
pub const MAX_BRUTEFORCE_PAIRS: u64 = 20_000_000_000;

impl Renderer {
    pub fn new(ctx: Arc<Context>, scene: &Scene, settings: RenderSettings) -> Result<Self> {
        settings.validate()?;
        let camera = CameraSetup::choose(scene, &settings);
        let scene_gpu = SceneGpu::new(&ctx, scene, settings.textures).context("uploading the scene")?;
        let targets = FrameTargets::new(&ctx, settings.width, settings.height).context("allocating frame targets")?;
        let mut passes = Passes::new(&ctx, scene_gpu.set.layout, scene_gpu.textured, &targets).context("creating passes")?;
        if settings.verbose {
            let texture_materials = scene.materials.iter().filter(|m| m.base_color_texture.is_some()).count();
            if scene_gpu.textured {
                eprintln!(
                    "textures: {} ({:.1} MiB of texels, {texture_materials} textured materials): gbuffer, pathtrace and photon_emit use their textured variants",
                    scene_gpu.texture_count,
                    scene_gpu.texel_bytes as f64 / (1 << 20) as f64
                );
            } else if texture_materials > 0 {
                eprintln!("textures: off (--textures off): {texture_materials} textured materials use their base colour factor; no texture code compiled in");
            } else {
                eprintln!("textures: none in the scene: untextured shader variants, no texture bindings");
            }
        }
        let photons = if settings.needs_vpls() {
            let pass = PhotonEmitPass::new(&ctx, scene_gpu.set.layout, scene_gpu.textured, &scene_gpu.lights, settings.photon_settings())
                .context("creating the photon pass")?;
            let stats = pass.run(scene_gpu.set.set).context("tracing photons")?;
            if settings.verbose {
                eprintln!(
                    "photon_emit: ran once before frame 0 (static scene): {} direct + {} indirect VPLs from {} paths in {:.1} GPU ms",
                    stats.direct_vpls, stats.indirect_vpls, stats.paths, stats.gpu_ms
                );
            }
            Some((pass, stats))
        } else {
            if settings.verbose {
                eprintln!("photon_emit: skipped (mode {} uses no VPLs and none are dumped)", settings.mode.name());
            }
            None
        };
        if settings.view == View::Vpls {
            let (pass, stats) = photons.as_ref().expect("--view vpls builds the VPL set");
            let (lo, hi) = scene.world_bounds();
            let radius = settings.vpl_radius.unwrap_or(0.0025 * (hi - lo).length().max(1e-6));
            passes.vpl_view = Some(VplViewPass::new(
                &ctx,
                scene_gpu.set.layout,
                &targets,
                &pass.vpls,
                PhotonEmitPass::vpl_count(stats),
                radius,
            )?);
        }
        let vpl = match (&photons, settings.mode.uses_vpls()) {
            (Some((pass, stats)), true) => {
                Some(Self::vpl_setup(&ctx, scene, &settings, &scene_gpu, &targets, &mut passes, pass, stats)?)
            }
            _ => None,
        };
        let timer = GpuTimer::new(&ctx, 32)?;
        let readback = crate::vk::Buffer::new(
            &ctx,
            "frame.counters_readback",
            4 * (RAY_SLOTS.len() as u64 + 1),
            vk::BufferUsageFlags::TRANSFER_DST,
            gpu_allocator::MemoryLocation::GpuToCpu,
        )?;
        // SAFETY: valid device and pool; destroyed in Drop.
        let (cmd, fence) = unsafe {
            let cmd = ctx.device.allocate_command_buffers(
                &vk::CommandBufferAllocateInfo::default()
                    .command_pool(ctx.command_pool)
                    .level(vk::CommandBufferLevel::PRIMARY)
                    .command_buffer_count(1),
            )?[0];
            ctx.set_name(cmd, "frame");
            let fence = ctx.device.create_fence(&vk::FenceCreateInfo::default(), None)?;
            (cmd, fence)
        };
        Ok(Self {
            settings,
            camera,
            scene: scene_gpu,
            targets,
            passes,
            timer,
            readback,
            cmd,
            fence,
            accumulated: 0,
            frame_index: 0,
            gbuffer_valid: false,
            nonfinite_samples: 0,
            photons,
            pass_times: BTreeMap::new(),
            pass_rays: BTreeMap::new(),
            vpl,
            current_reservoirs: 0,
            history_valid: false,
            ctx,
        })
    }

    /// The VPL modes' shared inputs and passes: alias table over the VPL powers (power source
    /// only), Yuksel radius, reservoirs, and only the passes the mode uses.
    #[allow(clippy::too_many_arguments)]
    fn vpl_setup(
        ctx: &Arc<Context>,
        scene: &Scene,
        settings: &RenderSettings,
        scene_gpu: &SceneGpu,
        targets: &FrameTargets,
        passes: &mut Passes,
        photon_pass: &PhotonEmitPass,
        stats: &PhotonStats,
    ) -> Result<VplSetup> {
        let vpl_count = PhotonEmitPass::vpl_count(stats);
        let layout = scene_gpu.set.layout;
        let mode = settings.mode;
        if mode == Mode::Bruteforce {
            let pairs = targets.pixels() as u64 * vpl_count as u64;
            anyhow::ensure!(
                pairs <= MAX_BRUTEFORCE_PAIRS,
                "--mode bruteforce: {}×{} pixels × {vpl_count} VPLs = {pairs} shadow rays per frame, over the limit of \
                 {MAX_BRUTEFORCE_PAIRS}; use a smaller image (--width/--height) or fewer VPLs (--vpls-direct/--vpls-indirect)",
                settings.width,
                settings.height
            );
        }
        let need_power = mode.uses_reservoirs() && settings.candidate_source == CandidateSource::Power && mode != Mode::Uniform;
        let usage = ash::vk::BufferUsageFlags::STORAGE_BUFFER;
        let mut total_vpl_lum = 0.0f64;
        let alias = if need_power {
            let vpls = photon_pass.read_vpls(stats)?;
            let weights: Vec<f64> = vpls.iter().map(|v| crate::lights::luminance(Vec3::from(v.flux)).max(0.0) as f64).collect();
            total_vpl_lum = weights.iter().sum();
            anyhow::ensure!(total_vpl_lum > 0.0, "--candidate-source power: the VPLs carry no power (empty or black scene)");
            let table = crate::lights::alias_table(&weights);
            crate::vk::Buffer::with_data(ctx, "restir_initial.vpl_alias", bytemuck::cast_slice(&table), usage)?
        } else {
            // The binding is declared by the shader but not read without the power source.
            crate::vk::Buffer::with_data(ctx, "restir_initial.vpl_alias(unused)", &[0u8; 8], usage)?
        };
        let (yuksel_radius, yuksel_radius_source) = match settings.attenuation {
            Attenuation::InverseSquare => (None, None),
            Attenuation::Yuksel => match settings.yuksel_radius {
                Some(r) => (Some(r), Some("--yuksel-radius")),
                None => {
                    let area = scene.surface_area();
                    let r = (area / (std::f64::consts::PI * vpl_count.max(1) as f64)).sqrt() as f32;
                    let r = if r > 0.0 && r.is_finite() { r } else { 1e-3 };
                    (Some(r), Some("mean VPL spacing sqrt(scene area / (pi * VPL count))"))
                }
            },
        };
        let r = &settings.restir;
        let unbiased = mode == Mode::Restir && r.bias == Bias::Unbiased;
        let mut flags = 0;
        if mode == Mode::Restir && r.initial_visibility() {
            flags |= VPL_FLAG_INITIAL_VISIBILITY;
        }
        if unbiased {
            flags |= VPL_FLAG_UNBIASED;
        }
        if !settings.aa {
            flags |= VPL_FLAG_SAME_DOMAIN;
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
        if mode == Mode::Bruteforce {
            passes.vpl.bruteforce = Some(VplBruteforcePass::new(ctx, layout, targets, &inputs)?);
        } else if mode.uses_reservoirs() {
            let res = Reservoirs::new(ctx, targets.pixels())?;
            passes.vpl.initial = Some(RestirInitialPass::new(ctx, layout, targets, &inputs, &res)?);
            passes.vpl.shade = Some(VplShadePass::new(ctx, layout, targets, &inputs, &res)?);
            if mode == Mode::Restir {
                if r.temporal {
                    let prev = if unbiased && settings.aa {
                        let buf = crate::vk::Buffer::new(
                            ctx,
                            "restir_temporal.prev_surfaces",
                            targets.surfaces.size,
                            ash::vk::BufferUsageFlags::STORAGE_BUFFER | ash::vk::BufferUsageFlags::TRANSFER_DST,
                            gpu_allocator::MemoryLocation::GpuOnly,
                        )?;
                        passes.prev_surfaces = Some(buf);
                        passes.prev_surfaces.as_ref().expect("just set")
                    } else {
                        &targets.surfaces
                    };
                    passes.vpl.temporal = Some(RestirTemporalPass::new(ctx, layout, targets, prev, &inputs, &res)?);
                }
                if r.spatial_passes > 0 && r.spatial_neighbours > 0 {
                    passes.vpl.spatial = Some(RestirSpatialPass::new(ctx, layout, targets, &inputs, &res)?);
                }
            }
            reservoirs = Some(res);
        }
        if settings.verbose {
            eprintln!(
                "vpl: {vpl_count} VPLs, attenuation {:?}{}, {} candidate(s) from the {} source",
                settings.attenuation,
                yuksel_radius.map(|r| format!(" (r = {r:.4})")).unwrap_or_default(),
                params.candidates,
                if need_power { "power" } else { "uniform" }
            );
        }
        Ok(VplSetup {
            vpl_count,
            yuksel_radius,
            yuksel_radius_source,
            total_vpl_lum,
            params,
            _alias: alias,
            reservoirs,
        })
    }

    /// What the next frame will run. `preview`: also run the tonemap pass.
    pub fn plan(&self, preview: bool) -> FramePlan {
        let s = &self.settings;
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
        let vpl = match &self.vpl {
            Some(v) => VplFrame { params: v.params, restir: *r, view: s.view, current: self.current_reservoirs },
            None => VplFrame::default(),
        };
        let gbuffer = if s.aa {
            Step::Run
        } else if self.gbuffer_valid {
            Step::Skip("camera still and no --aa: primary hits traced once")
        } else {
            Step::Run
        };
        FramePlan {
            keep_previous_gbuffer: self.passes.prev_surfaces.is_some() && self.gbuffer_valid && gbuffer == Step::Run,
            gbuffer,
            pathtrace: shading(mode == Mode::Pt, "mode is not pt"),
            vpl_bruteforce: shading(mode == Mode::Bruteforce, "mode is not bruteforce"),
            restir_initial: shading(mode.uses_reservoirs(), "mode picks no VPLs per pixel"),
            restir_temporal: restir_step(
                r.temporal && self.history_valid,
                if r.temporal { "no history before the first frame" } else { "--temporal off" },
            ),
            restir_spatial: restir_step(
                r.spatial_passes > 0 && r.spatial_neighbours > 0,
                "--spatial-passes 0 or --spatial-neighbours 0",
            ),
            vpl_shade: shading(mode.uses_reservoirs(), "mode picks no VPLs per pixel"),
            vpl_view: match self.settings.view {
                View::Vpls => Step::Run,
                _ => Step::Skip("no --view vpls"),
            },
            accumulate: Step::Run,
            tonemap: if preview { Step::Run } else { Step::Skip("no preview needed this frame") },
            reset_accumulation: self.accumulated == 0,
            vpl,
        }
    }

    fn frame_constants(&self) -> GpuFrame {
        let s = &self.settings;
        let c = &self.camera;
        GpuFrame {
            camera_position: c.position.to_array(),
            tan_half_fov: (c.yfov * 0.5).tan(),
            camera_right: c.right.to_array(),
            aspect: s.width as f32 / s.height as f32,
            camera_up: c.up.to_array(),
            frame_index: self.frame_index,
            camera_forward: c.forward.to_array(),
            seed: s.seed,
            width: s.width,
            height: s.height,
            max_bounces: s.max_bounces,
            flags: if s.aa { FRAME_AA } else { 0 },
            light_count: self.scene.lights.lights.len() as u32,
            instance_count: self.scene.instance_count as u32,
            total_light_power: self.scene.lights.total_power_lum as f32,
            exposure: 2f32.powf(s.exposure),
            accumulated_frames: self.accumulated + 1,
            ..Default::default()
        }
    }

    /// Renders and accumulates one frame; waits for it to finish.
    pub fn render_frame(&mut self, preview: bool) -> Result<FrameStats> {
        let start = std::time::Instant::now();
        let plan = self.plan(preview);
        if self.settings.verbose && (self.frame_index == 0 || (preview && self.frame_index + 1 == self.settings.frames)) {
            eprintln!("frame {} passes:\n{}", self.frame_index, plan.describe());
        }
        self.scene.write_frame(&self.frame_constants())?;
        let ctx = self.ctx.clone();
        let d = &ctx.device;
        // SAFETY: the previous submission of `cmd` has completed (we waited on the fence).
        unsafe {
            d.reset_command_buffer(self.cmd, vk::CommandBufferResetFlags::empty())?;
            d.begin_command_buffer(
                self.cmd,
                &vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
            )?;
        }
        self.timer.reset(self.cmd);
        self.passes.record_frame(&ctx, self.cmd, &mut self.timer, self.scene.set.set, &self.targets, &plan);
        let counters_size = 4 * RAY_SLOTS.len() as u64;
        let regions = [vk::BufferCopy::default().size(counters_size).dst_offset(0)];
        // SAFETY: buffers alive; the barrier in record_frame orders the copies after the passes.
        unsafe {
            d.cmd_copy_buffer(self.cmd, self.targets.ray_counter.raw, self.readback.raw, &regions);
            d.cmd_copy_buffer(
                self.cmd,
                self.targets.stats.raw,
                self.readback.raw,
                &[vk::BufferCopy::default().size(4).dst_offset(counters_size)],
            );
            d.end_command_buffer(self.cmd)?;
            let cmds = [self.cmd];
            let submit = [vk::SubmitInfo::default().command_buffers(&cmds)];
            d.reset_fences(&[self.fence])?;
            d.queue_submit(ctx.queue, &submit, self.fence).context("vkQueueSubmit (frame)")?;
            d.wait_for_fences(&[self.fence], true, u64::MAX).context("waiting for the frame (device lost?)")?;
        }
        let raw_ms = self.timer.collect()?;
        // One entry per pass: repeated dispatches of a pass (restir_spatial ×n) are summed.
        let mut pass_ms: Vec<(&'static str, f64)> = Vec::new();
        for (name, ms) in raw_ms {
            match pass_ms.iter_mut().find(|(n, _)| *n == name) {
                Some(entry) => entry.1 += ms,
                None => pass_ms.push((name, ms)),
            }
        }
        for (name, ms) in &pass_ms {
            self.pass_times.entry(name).or_default().push(*ms);
        }
        let n_slots = RAY_SLOTS.len();
        let counters: Vec<u32> = bytemuck::cast_slice(&self.readback.read(0, 4 * (n_slots + 1))?).to_vec();
        self.nonfinite_samples = counters[n_slots] as u64;
        let primary = if plan.gbuffer == Step::Run { self.targets.pixels() as u64 } else { 0 };
        let mut rays_by_pass = vec![("gbuffer", primary)];
        for (slot, name) in RAY_SLOTS.iter().enumerate() {
            if counters[slot] > 0 {
                rays_by_pass.push((name, counters[slot] as u64));
            }
        }
        for (name, n) in &rays_by_pass {
            self.pass_rays.entry(name).or_default().push(*n);
        }
        if plan.gbuffer == Step::Run {
            self.gbuffer_valid = true;
        }
        if plan.vpl_shade == Step::Run {
            // The final reservoirs become the next frame's history; the other buffer is free.
            self.current_reservoirs = 1 - plan.vpl.final_buffer(plan.spatial_passes());
            self.history_valid = true;
        }
        self.accumulated += 1;
        self.frame_index += 1;
        let rays = rays_by_pass.iter().map(|r| r.1).sum();
        Ok(FrameStats { pass_ms, rays, rays_by_pass, wall_ms: start.elapsed().as_secs_f64() * 1e3 })
    }

    /// Starts a new, independent accumulation with pixel seed `seed`: the VPL set, G-buffer and
    /// pipelines stay; the running mean, the ReSTIR history and the frame counter restart. (The
    /// photon pass keeps the VPLs it traced with the original seed.)
    pub fn restart(&mut self, seed: u32) {
        self.settings.seed = seed;
        self.accumulated = 0;
        self.frame_index = 0;
        self.history_valid = false;
        self.pass_times.clear();
        self.pass_rays.clear();
    }

    /// Starts a new accumulation but keeps everything else: the frame counter (so random numbers
    /// continue), the ReSTIR history and the G-buffer. Timing and ray statistics restart too.
    /// Used after warm-up frames, so that ReSTIR is measured in its steady state.
    pub fn reset_accumulation(&mut self) {
        self.accumulated = 0;
        self.pass_times.clear();
        self.pass_rays.clear();
    }

    /// Rays per pixel per frame, by the pass that traced them, over the frames so far.
    pub fn rays_per_pixel_by_pass(&self) -> BTreeMap<String, crate::output::TimingStats> {
        let pixels = self.targets.pixels() as f64;
        self.pass_rays
            .iter()
            .map(|(k, v)| (k.to_string(), crate::output::TimingStats::of(&v.iter().map(|n| *n as f64 / pixels).collect::<Vec<_>>())))
            .collect()
    }

    /// The VPL setup as summary.json reports it.
    pub fn vpl_summary(&self) -> Option<VplSummary> {
        self.vpl.as_ref().map(|v| VplSummary {
            vpl_count: v.vpl_count,
            yuksel_radius: v.yuksel_radius,
            yuksel_radius_source: v.yuksel_radius_source,
            candidates: if self.settings.mode.uses_reservoirs() { v.params.candidates } else { 0 },
            candidate_source: if v.params.source == 1 { "power" } else { "uniform" },
            initial_visibility: v.params.flags & VPL_FLAG_INITIAL_VISIBILITY != 0,
            unbiased_reuse: v.params.flags & VPL_FLAG_UNBIASED != 0,
        })
    }

    /// The final reservoirs of the last frame (VPL modes with reservoirs).
    pub fn read_reservoirs(&self) -> Result<Option<Vec<crate::gpu_types::GpuReservoir>>> {
        let Some(res) = self.vpl.as_ref().and_then(|v| v.reservoirs.as_ref()) else {
            return Ok(None);
        };
        let last = 1 - self.current_reservoirs;
        let bytes = read_back(&self.ctx, res.buffer(last))?;
        let all: &[crate::gpu_types::GpuReservoir] = bytemuck::cast_slice(&bytes);
        Ok(Some(all[..self.targets.pixels() as usize].to_vec()))
    }

    /// The VPL set (direct first, then indirect), when the run has one.
    pub fn read_vpls(&self) -> Result<Option<Vec<crate::gpu_types::GpuVpl>>> {
        self.photons.as_ref().map(|(pass, stats)| pass.read_vpls(stats)).transpose()
    }

    /// The running mean, row 0 at the top, RGB.
    pub fn read_mean(&self) -> Result<Vec<[f32; 3]>> {
        let bytes = read_back(&self.ctx, &self.targets.mean)?;
        let v: &[[f32; 4]] = bytemuck::cast_slice(&bytes);
        Ok(v[..self.targets.pixels() as usize].iter().map(|p| [p[0], p[1], p[2]]).collect())
    }

    /// Per-pixel sample variance of the accumulated frames (unbiased, n − 1), RGB.
    pub fn read_variance(&self) -> Result<Vec<[f32; 3]>> {
        let n = self.accumulated as f64;
        let sums = read_back(&self.ctx, &self.targets.accum_sum)?;
        let comp = read_back(&self.ctx, &self.targets.accum_compensation)?;
        let sq = read_back(&self.ctx, &self.targets.accum_squares)?;
        let (s, c, q): (&[[f32; 4]], &[[f32; 4]], &[[f32; 4]]) =
            (bytemuck::cast_slice(&sums), bytemuck::cast_slice(&comp), bytemuck::cast_slice(&sq));
        Ok((0..self.targets.pixels() as usize)
            .map(|i| {
                let mut out = [0f32; 3];
                for ch in 0..3 {
                    let sum = s[i][ch] as f64 + c[i][ch] as f64;
                    let mean = sum / n;
                    let var = if n > 1.0 { ((q[i][ch] as f64 - n * mean * mean) / (n - 1.0)).max(0.0) } else { 0.0 };
                    out[ch] = var as f32;
                }
                out
            })
            .collect())
    }

    /// The tonemapped preview (RGBA8, sRGB), valid after a frame rendered with `preview = true`.
    pub fn read_preview(&self) -> Result<Vec<u8>> {
        let mut bytes = read_back(&self.ctx, &self.targets.preview)?;
        bytes.truncate(self.targets.pixels() as usize * 4);
        Ok(bytes)
    }
}

impl Drop for Renderer {
    fn drop(&mut self) {
        // SAFETY: wait for idle, then free the frame's command buffer and fence.
        unsafe {
            let _ = self.ctx.device.device_wait_idle();
            self.ctx.device.destroy_fence(self.fence, None);
            self.ctx.device.free_command_buffers(self.ctx.command_pool, &[self.cmd]);
        }
    }
}
