//! `bench --rays`: this device's raw ray rate on each scene — coherent primary rays, incoherent
//! shadow rays of random length and incoherent closest-hit ("bounce") rays, with nothing else in
//! the shader (shaders/bench/ray_rate.comp) — and every tracing pass's rays per second (in real
//! frames, and the photon pass) as a share of the raw rate of its kind of ray.

use std::sync::Arc;

use anyhow::{Context as _, Result};
use ash::vk;
use serde::Serialize;

use crate::camera::Camera;
use crate::gpu_types::{GpuFrame, RAY_RATE_BOUNCE, RAY_RATE_PRIMARY, RAY_RATE_SHADOW};
use crate::output::TimingStats;
use crate::renderer::Renderer;
use crate::scene::Scene;
use crate::scene_gpu::SceneGpu;
use crate::settings::{Mode, RenderSettings, RestirSettings};
use crate::shaders;
use crate::passes::desc::{push_constants, PassDesc};
use crate::vk::pipeline::storage;
use crate::vk::{Buffer, Context, DescriptorSet, GpuTimer};

push_constants! {
    struct Push {
        bounds_lo: [f32; 3],
        mode: u32,
        bounds_hi: [f32; 3],
        dispatch_index: u32,
    }
}

/// The kernel's interface, checked against its SPIR-V by tests/layout.rs like every pass's.
pub const RAY_RATE_DESC: PassDesc = PassDesc::new("ray_rate", shaders::BENCH_RAY_RATE, [8, 8, 1])
    .with_raygen(shaders::BENCH_RAY_RATE_RAYGEN)
    .with_push(Push::LAYOUT)
    .with_bindings(&[storage(0, "sink")]);

/// One tracing pass in a real frame against the raw rate of its kind of ray.
#[derive(Clone, Debug, Serialize)]
pub struct PassRate {
    pub mode: String,
    pub pass: String,
    /// None for the photon pass, which traces per VPL, not per pixel.
    pub rays_per_pixel: Option<f64>,
    /// Rays of one frame (of one photon pass for photon_emit).
    pub rays: f64,
    pub gpu_ms: f64,
    pub mrays_per_s: f64,
    /// The raw rate it is measured against.
    pub against: RawKind,
    /// mrays_per_s / the raw rate it is measured against; NaN (null in JSON, "–" in the table)
    /// where that raw rate is 0.
    pub share: f64,
}

/// The raw rate a pass is measured against.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum RawKind {
    /// Coherent camera rays: the G-buffer pass.
    #[serde(rename = "primary")]
    Primary,
    /// Shadow rays of random length: every pass that traces visibility.
    #[serde(rename = "shadow")]
    Shadow,
    /// Closest-hit rays from surface to surface: the photon pass.
    #[serde(rename = "bounce")]
    Bounce,
    /// A closest-hit and a shadow ray per bounce (the path tracer), so the raw time per ray is the
    /// mean of the two kinds'.
    #[serde(rename = "bounce+shadow")]
    BounceAndShadow,
}

impl RawKind {
    /// The kind a real frame's tracing pass is measured against, by the pass's name.
    fn of_pass(name: &str) -> Self {
        match name {
            crate::passes::GbufferPass::NAME => Self::Primary,
            crate::passes::PathtracePass::NAME => Self::BounceAndShadow,
            crate::passes::PhotonEmitPass::NAME => Self::Bounce,
            _ => Self::Shadow,
        }
    }

    /// As the table and the JSON name it.
    pub fn label(self) -> &'static str {
        match self {
            Self::Primary => "primary",
            Self::Shadow => "shadow",
            Self::Bounce => "bounce",
            Self::BounceAndShadow => "bounce+shadow",
        }
    }
}

/// The raw rates and the passes of one scene.
#[derive(Clone, Debug, Serialize)]
pub struct RayRate {
    pub scene: String,
    pub triangles: usize,
    pub width: u32,
    pub height: u32,
    /// Mrays/s of each timed dispatch, half timed before the passes and half after them.
    pub primary: TimingStats,
    pub shadow: TimingStats,
    pub bounce: TimingStats,
    /// Median raw rate after the passes over the median before, per kind (primary, shadow,
    /// bounce): the machine's drift over the measurement, which the shares' two sides straddle.
    pub drift: [f64; 3],
    pub passes: Vec<PassRate>,
}

/// Frame constants that ray_rate.comp reads: the camera and the image size.
fn frame_for(camera: &Camera, width: u32, height: u32) -> GpuFrame {
    let mut f: GpuFrame = bytemuck::Zeroable::zeroed();
    f.camera_position = camera.position.to_array();
    f.tan_half_fov = (camera.yfov * 0.5).tan();
    f.camera_right = camera.right.to_array();
    f.aspect = width as f32 / height as f32;
    f.camera_up = camera.up.to_array();
    f.camera_forward = camera.forward.to_array();
    f.width = width;
    f.height = height;
    f
}

/// The modes whose frames `measure` renders: label, mode, `--compensate`, `--initial-visibility`.
const MODES: [(&str, Mode, bool, bool); 6] = [
    ("uniform", Mode::Uniform, false, false),
    ("ris", Mode::Ris, false, false),
    ("restir", Mode::Restir, false, false),
    ("restir --initial-visibility on", Mode::Restir, false, true),
    ("restir --compensate", Mode::Restir, true, false),
    ("pt", Mode::Pt, false, false),
];

/// The label of the photon pass's row.
pub const PHOTONS_LABEL: &str = "photons";

/// Below this many pixels a raw dispatch times its launch rather than its rays (`bench --rays` warns).
pub const SMALLEST_MEANINGFUL_PIXELS: u64 = 256 * 256;

/// What `bench --rays` says once, before its scenes, of a size too small to measure rays at.
pub fn small_size_warning(width: u32, height: u32) -> Option<String> {
    // At 8×8 the photon pass showed 2.5× and the path tracer 1.3× the raw rate: a dispatch that
    // small times its launch, not its rays.
    (u64::from(width) * u64::from(height) < SMALLEST_MEANINGFUL_PIXELS).then(|| {
        format!(
            "bench --rays at {width}×{height}: the raw dispatches are bound by their launch below {SMALLEST_MEANINGFUL_PIXELS} pixels, \
             so shares there (above 100 % among them) say nothing about ray rates; the photon pass traces its 100k + 100k VPLs \
             whatever the size. Measure at 1280×720 (the default)"
        )
    })
}

/// Times `dispatches` dispatches of each raw ray kind (after one untimed warm-up), half before and
/// half after the passes (at least one each), which are: `frames` frames (after one warm-up, with
/// `--aa` so primary rays are traced every frame) of each of [`MODES`], and the photons (100k +
/// 100k VPLs, the defaults) traced `frames` times more.
pub fn measure(ctx: &Arc<Context>, scene_path: &std::path::Path, width: u32, height: u32, dispatches: u32, frames: u32) -> Result<RayRate> {
    anyhow::ensure!(dispatches > 0 && frames > 0, "bench --rays needs at least one timed dispatch and frame");
    ctx.check_launch_size(width, height)?;
    // The size every mode measured after the raw dispatches must take, checked before them (its
    // one-word-a-pixel sink stays within the per-pixel limit).
    crate::passes::FrameTargets::check_size(ctx, width, height)?;
    let scene = Scene::load(scene_path)?;
    let gpu = Arc::new(SceneGpu::new(ctx, &scene, true, crate::vk::accel::MERGE_MAX_TRIANGLES)?);
    let set = DescriptorSet::with_variants(ctx, "ray_rate.scene", gpu.bindings, 1)?;
    gpu.write_set(&set)?;
    let camera = Camera::initial(&gpu.info, None);
    let frame = frame_for(&camera, width, height);
    let frame_buffer = Buffer::with_data(ctx, "ray_rate.frame", bytemuck::bytes_of(&frame), vk::BufferUsageFlags::UNIFORM_BUFFER)?;
    set.write_buffer_in(0, 8, &frame_buffer)?;
    let pixels = width as u64 * height as u64;
    let sink = Buffer::with_data(ctx, "ray_rate.sink", &vec![0u8; (pixels * 4) as usize], vk::BufferUsageFlags::STORAGE_BUFFER)?;
    // A compute pipeline with ray queries, a ray-tracing pipeline otherwise: the raw rate of the
    // way this context traces.
    let pipeline = RAY_RATE_DESC.pipeline(ctx, set.layout).buffers(&[(0, &sink)]).build()?;
    let (lo, hi) = gpu.info.bounds;
    let mut timer = GpuTimer::new(ctx, 4)?;
    let mut rate = |mode: u32, index: u32| -> Result<f64> {
        let push = Push { bounds_lo: lo.to_array(), mode, bounds_hi: hi.to_array(), dispatch_index: index };
        ctx.one_shot(|cmd| {
            timer.reset(cmd);
            timer.begin(cmd, "ray_rate");
            pipeline.dispatch_2d(cmd, set.set, bytemuck::bytes_of(&push), width, height);
            timer.end(cmd);
        })?;
        let ms: f64 = timer.collect()?.iter().map(|(_, ms)| ms).sum();
        Ok(if ms > 0.0 { pixels as f64 / (ms * 1e3) } else { 0.0 })
    };
    let kinds = [RAY_RATE_PRIMARY, RAY_RATE_SHADOW, RAY_RATE_BOUNCE];
    for kind in kinds {
        rate(kind, 0)?; // warm-up: shader compilation
    }
    // The raw rates are timed before the passes and again after them (half the dispatches each,
    // at least one), so that a share's two sides straddle the same stretch of the machine's drift
    // (minutes at 1280×720 on lavapipe, ±30 % there); the drift is reported.
    let mut raw = |first: u32, n: u32| -> Result<[Vec<f64>; 3]> {
        let mut samples = [Vec::new(), Vec::new(), Vec::new()];
        for i in first..first + n {
            // Interleaved so drift on a shared machine hits all kinds alike.
            for (kind, out) in kinds.into_iter().zip(samples.iter_mut()) {
                out.push(rate(kind, i)?);
            }
        }
        Ok(samples)
    };
    let half = dispatches.div_ceil(2);
    let before = raw(1, half)?;

    let mut passes = Vec::new();
    for (label, mode, compensate, initial_visibility) in MODES {
        let settings = RenderSettings {
            scene: scene_path.to_path_buf(),
            mode,
            width,
            height,
            frames: frames + 1,
            aa: true,
            compensate,
            restir: RestirSettings { initial_visibility: initial_visibility.then_some(true), ..Default::default() },
            // Passes apart, so that each tracing pass has its own rate (fused, the spatial
            // reuse's rays and the shading's would share one row).
            fuse_passes: Some(false),
            ..Default::default()
        };
        let mut r = Renderer::new(ctx.clone(), gpu.clone(), settings).with_context(|| format!("bench --rays: {label}"))?;
        r.render_frame(&camera, false)?; // warm-up
        r.reset_accumulation()?;
        let log_before = r.log().clone();
        for _ in 0..frames {
            r.render_frame(&camera, false)?;
        }
        let log = r.log();
        for (name, rays) in &log.pass_rays {
            let skip = log_before.pass_rays.get(name).map(|v| v.len()).unwrap_or(0);
            let total_rays: u64 = rays.iter().skip(skip).sum();
            let skip_ms = log_before.pass_ms.get(name).map(|v| v.len()).unwrap_or(0);
            let total_ms: f64 = log.pass_ms.get(name).map(|v| v.iter().skip(skip_ms).sum()).unwrap_or(0.0);
            if total_rays == 0 || total_ms <= 0.0 {
                continue;
            }
            let mrays = total_rays as f64 / (total_ms * 1e3);
            let against = RawKind::of_pass(name);
            passes.push(PassRate {
                mode: label.to_string(),
                pass: name.to_string(),
                rays_per_pixel: Some(total_rays as f64 / (pixels as f64 * frames as f64)),
                rays: total_rays as f64 / frames as f64,
                gpu_ms: total_ms / frames as f64,
                mrays_per_s: mrays,
                against,
                share: 0.0, // below, once the raw rates after the passes are in
            });
        }
    }

    // The photon pass: its paths' closest-hit rays against the raw bounce rate.
    let settings = RenderSettings { scene: scene_path.to_path_buf(), ..Default::default() };
    // Only the path batches trace rays: the direct VPLs and the flux normalisation are left out.
    let timing = crate::eval::bench::time_photons(ctx, &gpu, &settings, frames).context("bench --rays: photons")?;
    let (ms, stats) = (timing.paths_gpu_ms, timing.stats);
    if stats.rays > 0 && ms > 0.0 {
        let mrays = stats.rays as f64 / (ms * 1e3);
        passes.push(PassRate {
            mode: PHOTONS_LABEL.to_string(),
            pass: crate::passes::PhotonEmitPass::NAME.to_string(),
            rays_per_pixel: None,
            rays: stats.rays as f64,
            gpu_ms: ms,
            mrays_per_s: mrays,
            against: RawKind::of_pass(crate::passes::PhotonEmitPass::NAME),
            share: 0.0,
        });
    }
    let after = raw(1 + half, half)?;
    let median = |v: &[f64]| TimingStats::of(v).median;
    let drift: [f64; 3] = std::array::from_fn(|k| {
        let (b, a) = (median(&before[k]), median(&after[k]));
        if b > 0.0 { a / b } else { f64::NAN }
    });
    let [primary, shadow, bounce] = std::array::from_fn(|k| TimingStats::of(&[before[k].clone(), after[k].clone()].concat()));
    // Per ray, a path tracer's bounce costs a closest-hit and a shadow ray: the mean raw time.
    let bounce_and_shadow = 2.0 / (1.0 / bounce.median + 1.0 / shadow.median);
    for p in &mut passes {
        let raw = match p.against {
            RawKind::Primary => primary.median,
            RawKind::BounceAndShadow => bounce_and_shadow,
            RawKind::Bounce => bounce.median,
            RawKind::Shadow => shadow.median,
        };
        // No raw rate (a dispatch timed at 0 ms): no share, shown as "–".
        p.share = if raw > 0.0 && raw.is_finite() { p.mrays_per_s / raw } else { f64::NAN };
    }
    let label = scene_path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| scene_path.display().to_string());
    Ok(RayRate { scene: label, triangles: gpu.triangle_count, width, height, primary, shadow, bounce, drift, passes })
}

/// Markdown: the raw rates per scene, then every tracing pass's share.
pub fn markdown(rows: &[RayRate], device: &str) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let _ = writeln!(s, "Device: {device}\n");
    let _ = writeln!(
        s,
        "Raw rates: half the dispatches timed before the passes, half after them; drift: the median after over the median before \
         (primary / shadow / bounce). A share's two sides straddle that drift.\n"
    );
    let _ = writeln!(s, "| scene | triangles | size | Mrays/s (median, min–max): primary | shadow | bounce | drift |");
    let _ = writeln!(s, "|---|---:|---|---:|---:|---:|---|");
    let stats = |t: &TimingStats| format!("{:.2} ({:.2}–{:.2})", t.median, t.min, t.max);
    for r in rows {
        let drift = r.drift.map(|d| if d.is_finite() { format!("{d:.2}") } else { "–".into() }).join(" / ");
        let _ = writeln!(
            s,
            "| {} | {} | {}×{} | {} | {} | {} | {drift} |",
            r.scene,
            r.triangles,
            r.width,
            r.height,
            stats(&r.primary),
            stats(&r.shadow),
            stats(&r.bounce)
        );
    }
    let _ = writeln!(s, "\n| scene | mode | pass | rays / px | GPU ms | Mrays/s | share of raw rate |");
    let _ = writeln!(s, "|---|---|---|---:|---:|---:|---:|");
    for r in rows {
        for p in &r.passes {
            let per_pixel = p.rays_per_pixel.map(|x| format!("{x:.2}")).unwrap_or_else(|| format!("({:.0} rays)", p.rays));
            let _ = writeln!(
                s,
                "| {} | {} | {} | {per_pixel} | {:.1} | {:.2} | {} of {} |",
                r.scene,
                p.mode,
                p.pass,
                p.gpu_ms,
                p.mrays_per_s,
                if p.share.is_finite() { format!("{:.0}%", 100.0 * p.share) } else { "–".into() },
                p.against.label()
            );
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::RawKind;

    /// The JSON (serde's names) and the table (`label`) name each kind alike, and each pass that
    /// traces is measured against its own kind.
    #[test]
    fn raw_kinds_are_named_alike_in_json_and_table() {
        for kind in [RawKind::Primary, RawKind::Shadow, RawKind::Bounce, RawKind::BounceAndShadow] {
            assert_eq!(serde_json::to_string(&kind).unwrap(), format!("\"{}\"", kind.label()));
        }
        assert_eq!(RawKind::of_pass(crate::passes::GbufferPass::NAME), RawKind::Primary);
        assert_eq!(RawKind::of_pass(crate::passes::PathtracePass::NAME), RawKind::BounceAndShadow);
        assert_eq!(RawKind::of_pass(crate::passes::PhotonEmitPass::NAME), RawKind::Bounce);
        assert_eq!(RawKind::of_pass(crate::passes::RestirSpatialPass::NAME), RawKind::Shadow);
    }
}
