//! The renderer: scene on the GPU, frame targets, passes, and the per-frame submission.

use std::collections::BTreeMap;
use std::sync::Arc;

use anyhow::{Context as _, Result};
use ash::vk;
use glam::{Mat4, Vec3};

use crate::gpu_types::{GpuFrame, FRAME_AA};
use crate::passes::{FramePlan, FrameTargets, Passes, PhotonEmitPass, PhotonStats, Step, VplViewPass};
use crate::scene::Scene;
use crate::scene_gpu::SceneGpu;
use crate::settings::{Mode, RenderSettings, View};
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
    /// Per-pass GPU times of every frame so far.
    pub pass_times: BTreeMap<&'static str, Vec<f64>>,
    pub ctx: Arc<Context>,
}

impl Renderer {
    pub fn new(ctx: Arc<Context>, scene: &Scene, settings: RenderSettings) -> Result<Self> {
        settings.validate()?;
        let camera = CameraSetup::choose(scene, &settings);
        let scene_gpu = SceneGpu::new(&ctx, scene).context("uploading the scene")?;
        let targets = FrameTargets::new(&ctx, settings.width, settings.height).context("allocating frame targets")?;
        let mut passes = Passes::new(&ctx, scene_gpu.set.layout, &targets).context("creating passes")?;
        let photons = if settings.needs_vpls() {
            let pass = PhotonEmitPass::new(&ctx, scene_gpu.set.layout, &scene_gpu.lights, settings.photon_settings())
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
        let timer = GpuTimer::new(&ctx, 16)?;
        let readback = crate::vk::Buffer::new(
            &ctx,
            "frame.counters_readback",
            32,
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
            ctx,
        })
    }

    /// What the next frame will run. `preview`: also run the tonemap pass.
    pub fn plan(&self, preview: bool) -> FramePlan {
        FramePlan {
            gbuffer: if self.settings.aa {
                Step::Run
            } else if self.gbuffer_valid {
                Step::Skip("camera still and no --aa: primary hits traced once")
            } else {
                Step::Run
            },
            pathtrace: match (self.settings.view, self.settings.mode) {
                (View::Vpls, _) => Step::Skip("--view vpls draws the VPLs instead"),
                (View::Final, Mode::Pt) => Step::Run,
            },
            vpl_view: match self.settings.view {
                View::Vpls => Step::Run,
                View::Final => Step::Skip("no --view vpls"),
            },
            accumulate: Step::Run,
            tonemap: if preview { Step::Run } else { Step::Skip("no preview needed this frame") },
            reset_accumulation: self.accumulated == 0,
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
        let regions = [vk::BufferCopy::default().size(4).dst_offset(0)];
        // SAFETY: buffers alive; the barrier in record_frame orders the copies after the passes.
        unsafe {
            d.cmd_copy_buffer(self.cmd, self.targets.ray_counter.raw, self.readback.raw, &regions);
            d.cmd_copy_buffer(
                self.cmd,
                self.targets.stats.raw,
                self.readback.raw,
                &[vk::BufferCopy::default().size(4).dst_offset(4)],
            );
            d.end_command_buffer(self.cmd)?;
            let cmds = [self.cmd];
            let submit = [vk::SubmitInfo::default().command_buffers(&cmds)];
            d.reset_fences(&[self.fence])?;
            d.queue_submit(ctx.queue, &submit, self.fence).context("vkQueueSubmit (frame)")?;
            d.wait_for_fences(&[self.fence], true, u64::MAX).context("waiting for the frame (device lost?)")?;
        }
        let pass_ms = self.timer.collect()?;
        for (name, ms) in &pass_ms {
            self.pass_times.entry(name).or_default().push(*ms);
        }
        let counters: Vec<u32> = bytemuck::cast_slice(&self.readback.read(0, 8)?).to_vec();
        self.nonfinite_samples = counters[1] as u64;
        let primary = if plan.gbuffer == Step::Run { self.targets.pixels() as u64 } else { 0 };
        if plan.gbuffer == Step::Run {
            self.gbuffer_valid = true;
        }
        self.accumulated += 1;
        self.frame_index += 1;
        Ok(FrameStats { pass_ms, rays: primary + counters[0] as u64, wall_ms: start.elapsed().as_secs_f64() * 1e3 })
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
