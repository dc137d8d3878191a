//! Benchmarks (not tests): throughput figures measured from GPU timestamps.

use std::sync::Arc;

use anyhow::{Context as _, Result};
use serde::Serialize;

use crate::camera::{Camera, CameraPath};
use crate::output::TimingStats;
use crate::passes::photon_emit::PhotonStats;
use crate::renderer::Renderer;
use crate::scene::Scene;
use crate::scene_gpu::SceneGpu;
use crate::settings::RenderSettings;
use crate::vk::{Context, ContextOptions};

/// A context without validation on `device` and `scene` uploaded to it (textures on).
pub fn upload(scene: &Scene, device: Option<usize>) -> Result<(Arc<Context>, Arc<SceneGpu>)> {
    let ctx = Arc::new(Context::new(&ContextOptions { validate: false, device_index: device, ..Default::default() })?);
    let gpu = Arc::new(SceneGpu::new(&ctx, scene, true, crate::vk::accel::MERGE_MAX_TRIANGLES)?);
    Ok((ctx, gpu))
}

/// The scene at `scene_path` with its textures checked against the device `device` picks before
/// they are decoded (`Scene::load_for_device`).
fn load_checked(scene_path: &std::path::Path, device: Option<usize>) -> Result<Scene> {
    Scene::load_for_device(scene_path, true, &|| crate::vk::context::storage_buffer_range(device, None))
}

/// Primary-ray and path-tracing throughput of one scene.
#[derive(Clone, Debug, Serialize)]
pub struct CoreBench {
    pub device: String,
    pub scene: String,
    pub triangles: usize,
    pub width: u32,
    pub height: u32,
    pub frames: u32,
    /// GPU ms per pass (after one warm-up frame, which includes shader JIT on lavapipe).
    pub pass_ms: Vec<(String, TimingStats)>,
    pub gpu_ms_per_frame: TimingStats,
    pub primary_mrays_per_s: f64,
    pub pathtrace_mrays_per_s: f64,
    pub pathtrace_rays_per_pixel: f64,
}

/// Renders `frames` frames (plus one warm-up) with anti-aliasing on, so that the G-buffer's primary
/// rays are traced every frame, and reports throughput from the GPU timestamps.
pub fn core(scene_path: &std::path::Path, width: u32, height: u32, frames: u32, device: Option<usize>) -> Result<CoreBench> {
    let (ctx, scene) = upload(&load_checked(scene_path, device)?, device)?;
    let settings = RenderSettings {
        scene: scene_path.to_path_buf(),
        width,
        height,
        frames: frames + 1,
        aa: true,
        ..Default::default()
    };
    let camera = Camera::initial(&scene.info, None);
    let mut r = Renderer::new(ctx.clone(), scene.clone(), settings)?; // validates the settings
    r.render_frame(&camera, false)?; // warm-up: shader compilation, first-touch allocations
    r.reset_accumulation()?;
    for _ in 0..frames {
        r.render_frame(&camera, false)?;
    }
    let log = r.log();
    let pixels = (width * height) as f64;
    let gb = log.pass_stats().get("gbuffer").copied().unwrap_or_default();
    let pt_total_ms: f64 = log.pass_ms.get("pathtrace").map(|v| v.iter().sum()).unwrap_or(0.0);
    let pt_rays: f64 = log.pass_rays.get("pathtrace").map(|v| v.iter().sum::<u64>() as f64).unwrap_or(0.0);
    Ok(CoreBench {
        device: ctx.report.name.clone(),
        scene: scene_path.display().to_string(),
        triangles: scene.triangle_count,
        width,
        height,
        frames,
        pass_ms: log.pass_stats().into_iter().collect(),
        gpu_ms_per_frame: log.gpu(),
        primary_mrays_per_s: if gb.median > 0.0 { pixels / (gb.median * 1e3) } else { 0.0 },
        pathtrace_mrays_per_s: if pt_total_ms > 0.0 { pt_rays / (pt_total_ms * 1e3) } else { 0.0 },
        pathtrace_rays_per_pixel: pt_rays / (pixels * frames as f64),
    })
}

impl CoreBench {
    /// A Markdown report.
    pub fn markdown(&self) -> String {
        let mut s = format!(
            "Core benchmark: {} ({} triangles), {}x{}, {} frames, device {}\n\n| pass | median ms | min ms | max ms |\n|---|---:|---:|---:|\n",
            self.scene, self.triangles, self.width, self.height, self.frames, self.device
        );
        for (name, t) in &self.pass_ms {
            s += &format!("| {name} | {:.2} | {:.2} | {:.2} |\n", t.median, t.min, t.max);
        }
        s += &format!(
            "\nGPU ms per frame (median): {:.2}\nprimary rays: {:.2} Mrays/s\npath tracing: {:.2} Mrays/s ({:.2} rays per pixel per frame)\n",
            self.gpu_ms_per_frame.median, self.primary_mrays_per_s, self.pathtrace_mrays_per_s, self.pathtrace_rays_per_pixel
        );
        s
    }
}

/// A room with a ceiling light and a finely tessellated bumpy sphere of `2·rings·segments`
/// triangles (≥ 100k for the photon benchmark).
pub fn dense_scene(rings: u32, segments: u32) -> Result<Scene> {
    use crate::scene::generate::{closed_box, GltfBuilder};
    let mut b = GltfBuilder::new();
    let wall = b.material("wall", [0.7; 3], [0.0; 3], false);
    let red = b.material("red", [0.7, 0.1, 0.1], [0.0; 3], false);
    let lamp = b.material("lamp", [0.7; 3], [15.0, 14.0, 12.0], false);
    let room = closed_box(&mut b, "room", [-1.0, 0.0, -1.0], [1.0, 2.0, 1.0], wall, true);
    b.node("room", room, [0.0; 3]);
    let light = b.quad("lamp", [[-0.25, 1.99, -0.25], [0.25, 1.99, -0.25], [0.25, 1.99, 0.25], [-0.25, 1.99, 0.25]], lamp);
    b.node("lamp", light, [0.0; 3]);
    let mut positions = Vec::new();
    for r in 0..=rings {
        let theta = std::f32::consts::PI * r as f32 / rings as f32;
        for s in 0..=segments {
            let phi = 2.0 * std::f32::consts::PI * s as f32 / segments as f32;
            let bump = 1.0 + 0.06 * (7.0 * theta).sin() * (11.0 * phi).cos();
            let rad = 0.5 * bump;
            positions.push([rad * theta.sin() * phi.cos(), 0.7 + rad * theta.cos(), rad * theta.sin() * phi.sin()]);
        }
    }
    let mut indices = Vec::new();
    let row = segments + 1;
    for r in 0..rings {
        for s in 0..segments {
            let (a, c) = (r * row + s, (r + 1) * row + s);
            indices.extend_from_slice(&[a, a + 1, c, a + 1, c + 1, c]);
        }
    }
    let sphere = b.mesh("bumpy_sphere", &positions, None, &indices, red);
    b.node("bumpy_sphere", sphere, [0.0; 3]);
    b.camera("cam", [0.0, 1.0, 0.95], [0.0, 0.8, 0.0], [0.0, 1.0, 0.0], 1.2);
    Scene::from_gltf_slice(b.to_json_string().as_bytes(), None, "dense_scene")
}

/// Photon-pass timing for one scene.
#[derive(Clone, Debug, Serialize)]
pub struct PhotonBench {
    pub scene: String,
    pub triangles: usize,
    pub direct: u32,
    pub indirect_target: u32,
    /// Median over runs.
    pub gpu_ms: f64,
    pub paths: u64,
    /// Closest-hit rays of one run.
    pub rays: u64,
    pub paths_per_second: f64,
    /// Rays over the time of the path batches alone (the direct VPLs trace none).
    pub rays_per_second: f64,
    pub indirect_vpls: u32,
}

/// Times the photon pass `runs` times (after a warm-up) on `scene`.
pub fn photons(scene: &Scene, label: &str, direct: u32, indirect: u32, runs: u32, device: Option<usize>) -> Result<PhotonBench> {
    let (ctx, gpu) = upload(scene, device)?;
    let settings = RenderSettings { vpls_direct: direct, vpls_indirect: indirect, ..Default::default() };
    let PhotonTiming { gpu_ms, paths_gpu_ms, stats } = time_photons(&ctx, &gpu, &settings, runs)?;
    Ok(PhotonBench {
        scene: label.to_string(),
        triangles: scene.triangle_count(),
        direct,
        indirect_target: indirect,
        gpu_ms,
        paths: stats.paths,
        rays: stats.rays,
        paths_per_second: stats.paths as f64 / (gpu_ms * 1e-3),
        rays_per_second: stats.rays as f64 / (paths_gpu_ms * 1e-3),
        indirect_vpls: stats.indirect_vpls,
    })
}

/// The photon pass timed over several re-traces.
pub struct PhotonTiming {
    /// Median GPU ms of the whole pass.
    pub gpu_ms: f64,
    /// Median GPU ms of its photon path batches (the part that traces rays).
    pub paths_gpu_ms: f64,
    /// The last run's statistics (the counts are the same in every run: same seed).
    pub stats: PhotonStats,
}

/// `runs` re-traces of the photon pass with `settings`' VPL counts. The renderer's own first trace
/// (shader compilation) is the untimed warm-up; the image is tiny, since only the photon pass is
/// timed.
pub fn time_photons(ctx: &Arc<Context>, scene: &Arc<SceneGpu>, settings: &RenderSettings, runs: u32) -> Result<PhotonTiming> {
    let settings = RenderSettings { mode: crate::settings::Mode::Uniform, width: 8, height: 8, ..settings.clone() };
    let mut r = Renderer::new(ctx.clone(), scene.clone(), settings)?;
    let (mut total, mut paths) = (Vec::new(), Vec::new());
    let mut last = None;
    for _ in 0..runs.max(1) {
        let stats = r.retrace_photons()?;
        total.push(stats.gpu_ms);
        paths.push(stats.paths_gpu_ms);
        last = Some(stats);
    }
    Ok(PhotonTiming {
        gpu_ms: TimingStats::of(&total).median,
        paths_gpu_ms: TimingStats::of(&paths).median,
        stats: last.expect("at least one run"),
    })
}

/// One VPL mode's cost at one resolution.
#[derive(Clone, Debug, Serialize)]
pub struct ModeBench {
    pub label: String,
    pub width: u32,
    pub height: u32,
    pub frames: u32,
    /// The camera moved along the scene's path (G-buffer and reprojection every frame).
    pub moving: bool,
    /// Median GPU ms per pass.
    pub pass_ms: Vec<(String, f64)>,
    /// Median GPU ms per frame (sum of its passes).
    pub gpu_ms_per_frame: f64,
    /// Median rays per pixel per frame by pass.
    pub rays_per_pixel: Vec<(String, f64)>,
    pub rays_per_pixel_total: f64,
    /// This frame time over the uniform mode's at the same resolution (same run).
    pub ratio_to_uniform: f64,
}

/// The VPL modes the `bench --modes` table compares.
pub fn mode_cases() -> Vec<(&'static str, crate::settings::Mode, crate::settings::RestirSettings)> {
    use crate::settings::{Bias, Mode, RestirSettings};
    let restir = |bias, vis| RestirSettings { bias, initial_visibility: Some(vis), ..Default::default() };
    vec![
        ("uniform", Mode::Uniform, RestirSettings::default()),
        ("ris (32 candidates)", Mode::Ris, RestirSettings::default()),
        ("restir biased", Mode::Restir, restir(Bias::Biased, false)),
        ("restir unbiased, unshadowed targets", Mode::Restir, restir(Bias::Unbiased, false)),
        ("restir unbiased, visibility in targets", Mode::Restir, restir(Bias::Unbiased, true)),
    ]
}

/// Frame cost of uniform, RIS and ReSTIR on one scene at the given sizes with `direct + indirect`
/// VPLs: two warm-up frames (shader JIT, temporal history), then `frames` timed frames per mode,
/// interleaved across modes so the ratios share the machine's state. `moving`: the camera follows
/// the path committed beside the scene (`<scene>.path.json`, see [`moving_camera`]) and every frame
/// is displayed alone (progressive off), as in the window while flying; otherwise the camera stands
/// still at the scene's own and the G-buffer is traced once. `fusion`: [`fusion_cases`] instead of
/// [`mode_cases`]; `grid`: [`grid_cases`].
#[allow(clippy::too_many_arguments)]
pub fn modes(
    scene_path: &std::path::Path,
    sizes: &[(u32, u32)],
    direct: u32,
    indirect: u32,
    frames: u32,
    device: Option<usize>,
    moving: bool,
    fusion: bool,
    grid: bool,
) -> Result<Vec<ModeBench>> {
    let (ctx, scene) = upload(&load_checked(scene_path, device)?, device)?;
    modes_on(&ctx, &scene, scene_path, sizes, direct, indirect, frames, moving, fusion, grid)
}

/// [`modes`] on a context with the scene already uploaded.
#[allow(clippy::too_many_arguments)]
fn modes_on(
    ctx: &Arc<Context>,
    scene: &Arc<SceneGpu>,
    scene_path: &std::path::Path,
    sizes: &[(u32, u32)],
    direct: u32,
    indirect: u32,
    frames: u32,
    moving: bool,
    fusion: bool,
    grid: bool,
) -> Result<Vec<ModeBench>> {
    let path = if moving {
        let file = crate::eval::motion::path_file(scene_path);
        Some(CameraPath::load(&file).context("bench --modes --moving follows the camera path committed beside the scene")?)
    } else {
        None
    };
    let mut out = Vec::new();
    for &(width, height) in sizes {
        let base = RenderSettings {
            scene: scene_path.to_path_buf(),
            width,
            height,
            vpls_direct: direct,
            vpls_indirect: indirect,
            progressive: !moving,
            ..Default::default()
        };
        if fusion {
            out.extend(time_settings(ctx, scene, &fusion_cases(&base), frames, path.as_ref())?);
        } else if grid {
            out.extend(time_settings(ctx, scene, &grid_cases(&base), frames, path.as_ref())?);
        } else {
            out.extend(time_modes(ctx, scene, &base, &mode_cases(), frames, path.as_ref())?);
        }
    }
    Ok(out)
}

/// `bench --modes --fusion`: uniform, then biased and unbiased ReSTIR with their passes apart and
/// fused (`--fuse-passes off` / `on`), with `base`'s other settings.
pub fn fusion_cases(base: &RenderSettings) -> Vec<(String, RenderSettings)> {
    use crate::settings::{Bias, Mode, RestirSettings};
    let mut cases = vec![("uniform".to_string(), RenderSettings { mode: Mode::Uniform, ..base.clone() })];
    for (name, bias) in [("biased", Bias::Biased), ("unbiased", Bias::Unbiased)] {
        for (how, fuse_passes) in [("passes apart", false), ("fused", true)] {
            let restir = RestirSettings { bias, initial_visibility: Some(false), ..Default::default() };
            cases.push((format!("restir {name}, {how}"), RenderSettings { mode: Mode::Restir, restir, fuse_passes: Some(fuse_passes), ..base.clone() }));
        }
    }
    cases
}

/// Candidates per pixel of [`grid_cases`]' grid rows, and how many of them come from the grid:
/// half of the default 32, half of them from the grid, where RIS had less per-frame error than with
/// 32 uniform candidates on average on all three scenes (docs/performance.md, "The ReGIR grid,
/// built").
pub const GRID_CASE_CANDIDATES: (u32, u32) = (16, 8);

/// `bench --modes --grid`: uniform, then RIS and unbiased ReSTIR with the default 32 candidates,
/// with [`GRID_CASE_CANDIDATES`]`.0` uniform ones and with as many of which `.1` from the ReGIR
/// grid: the grid's cost at equal candidates, and against the default.
pub fn grid_cases(base: &RenderSettings) -> Vec<(String, RenderSettings)> {
    use crate::settings::{Bias, GridSettings, Mode, RestirSettings};
    let (m, g) = GRID_CASE_CANDIDATES;
    let grid = GridSettings { candidates: g, ..Default::default() };
    let mut cases = vec![("uniform".to_string(), RenderSettings { mode: Mode::Uniform, ..base.clone() })];
    let unbiased = RestirSettings { bias: Bias::Unbiased, initial_visibility: Some(false), ..Default::default() };
    for (name, mode, restir) in [("ris", Mode::Ris, RestirSettings::default()), ("restir unbiased", Mode::Restir, unbiased)] {
        cases.push((format!("{name}, {} candidates", base.candidates), RenderSettings { mode, restir, ..base.clone() }));
        cases.push((format!("{name}, {m} candidates"), RenderSettings { mode, restir, candidates: m, ..base.clone() }));
        cases.push((format!("{name}, {m} candidates ({g} from the grid)"), RenderSettings { mode, restir, candidates: m, grid, ..base.clone() }));
    }
    cases
}

/// The camera of timed frame `f` (0-based) on `path`: path frame f + 1, going back and forth
/// between the first and last keyframe, so that no two consecutive frames (the warm-up at the
/// path's start included) share a camera however many frames are timed.
pub fn moving_camera(path: &CameraPath, f: u32) -> Camera {
    // In u64: twice a span of 2^31 frames or more wrapped u32 (to 0: a division by zero).
    let (first, last) = path.frame_range();
    let (first, span) = (u64::from(first), u64::from(last.saturating_sub(first)).max(1));
    let t = (u64::from(f) + 1) % (2 * span);
    let along = if t <= span { t } else { 2 * span - t };
    path.at((first + along) as f32)
}

/// Frame cost of each of `cases` (label, mode, ReSTIR settings) with `base`'s other settings, from
/// the scene's camera (or along `path`, see [`time_settings`]): two warm-up frames per mode (shader
/// JIT, temporal history), then `frames` timed frames per mode, interleaved across modes (one frame
/// of each per round) so drift on a shared machine hits every mode alike. Ratios are to the first
/// case.
pub fn time_modes(
    ctx: &Arc<Context>,
    scene: &Arc<SceneGpu>,
    base: &RenderSettings,
    cases: &[(&str, crate::settings::Mode, crate::settings::RestirSettings)],
    frames: u32,
    path: Option<&CameraPath>,
) -> Result<Vec<ModeBench>> {
    let cases: Vec<(String, RenderSettings)> = cases
        .iter()
        .map(|(label, mode, restir)| (label.to_string(), RenderSettings { mode: *mode, restir: *restir, ..base.clone() }))
        .collect();
    time_settings(ctx, scene, &cases, frames, path)
}

/// Frame cost of each (label, settings) case, as [`time_modes`] measures it: two warm-up frames
/// each, then `frames` timed frames interleaved across the cases. Ratios are to the first case.
/// With a `path` the warm-up stands at its start and timed frame f uses [`moving_camera`].
pub fn time_settings(
    ctx: &Arc<Context>,
    scene: &Arc<SceneGpu>,
    cases: &[(String, RenderSettings)],
    frames: u32,
    path: Option<&CameraPath>,
) -> Result<Vec<ModeBench>> {
    // The path in the renderer's coordinates (the scene may have been recentred).
    let moved = path.map(|p| p.moved(-scene.info.origin));
    let path = moved.as_ref();
    let camera = match path {
        Some(p) => p.at(p.keyframes[0].frame as f32),
        None => Camera::initial(&scene.info, None),
    };
    let mut renderers = Vec::new();
    for (label, settings) in cases {
        let settings = RenderSettings { frames: frames + 2, ..settings.clone() };
        let (width, height) = (settings.width, settings.height);
        let mut r = Renderer::new(ctx.clone(), scene.clone(), settings)?;
        r.render_frame(&camera, false)?;
        r.render_frame(&camera, false)?;
        r.reset_accumulation()?;
        renderers.push((label, width, height, r));
    }
    for f in 0..frames {
        let camera = path.map_or(camera, |p| moving_camera(p, f));
        for (_, _, _, r) in renderers.iter_mut() {
            r.render_frame(&camera, false)?;
        }
    }
    let mut out = Vec::new();
    let mut first_ms = None;
    for (label, width, height, r) in renderers {
        let log = r.log();
        let gpu = log.gpu().median;
        let rays: Vec<(String, f64)> =
            log.rays_per_pixel_by_pass().into_iter().map(|(k, t)| (k, t.mean)).filter(|(_, n)| *n > 0.0).collect();
        let first = *first_ms.get_or_insert(gpu);
        out.push(ModeBench {
            label: label.to_string(),
            width,
            height,
            frames,
            moving: path.is_some(),
            pass_ms: log.pass_stats().into_iter().map(|(k, t)| (k, t.median)).collect(),
            gpu_ms_per_frame: gpu,
            // (+ 0.0: an empty sum of floats is -0.0, printed "-0.00" for a scene without rays.)
            rays_per_pixel_total: rays.iter().map(|r| r.1).sum::<f64>() + 0.0,
            rays_per_pixel: rays,
            ratio_to_uniform: if first > 0.0 { gpu / first } else { 0.0 },
        });
    }
    Ok(out)
}

/// Workgroup shapes `bench --workgroups` compares; the first is the default.
pub const WORKGROUP_SHAPES: [[u32; 2]; 7] = [[8, 8], [4, 4], [8, 4], [16, 4], [16, 16], [32, 8], [64, 1]];

/// One mode's per-pass cost at each workgroup shape.
#[derive(Clone, Debug, Serialize)]
pub struct WorkgroupBench {
    pub mode: String,
    pub width: u32,
    pub height: u32,
    pub frames: u32,
    /// (shape, median GPU ms per pass, median GPU ms per frame), shapes as [`WORKGROUP_SHAPES`].
    pub shapes: Vec<([u32; 2], Vec<(String, f64)>, f64)>,
}

/// Per-pass cost of the per-pixel passes at each of [`WORKGROUP_SHAPES`] (`--workgroup`), for
/// the default ReSTIR and the path tracer, with jittered primary rays so the G-buffer pass runs
/// every frame. Every shape of one mode is timed in one interleaved run ([`time_settings`]), so
/// the ratios to 8×8 share the machine's state.
pub fn workgroups(scene_path: &std::path::Path, width: u32, height: u32, frames: u32, device: Option<usize>) -> Result<Vec<WorkgroupBench>> {
    use crate::settings::Mode;
    let (ctx, scene) = upload(&load_checked(scene_path, device)?, device)?;
    // Every pass that takes the shape traces rays, and so runs as a ray-generation shader there.
    anyhow::ensure!(
        ctx.tracing != crate::vk::context::Tracing::Pipeline,
        "bench --workgroups: {} traces rays with {}, whose launches have no workgroups: every shape would \
         run the same code (RESTIR_VPL_TRACE=query measures them where the device has ray queries)",
        ctx.report.name,
        ctx.tracing.describe()
    );
    let mut out = Vec::new();
    for mode in [Mode::Restir, Mode::Pt] {
        let base = RenderSettings { scene: scene_path.to_path_buf(), mode, width, height, aa: true, ..Default::default() };
        let cases: Vec<(String, RenderSettings)> = WORKGROUP_SHAPES
            .iter()
            .map(|&workgroup| (format!("{}x{}", workgroup[0], workgroup[1]), RenderSettings { workgroup, ..base.clone() }))
            .collect();
        let rows = time_settings(&ctx, &scene, &cases, frames, None)?;
        out.push(WorkgroupBench {
            mode: format!("{mode:?}").to_lowercase(),
            width,
            height,
            frames,
            shapes: WORKGROUP_SHAPES.iter().zip(rows).map(|(&shape, r)| (shape, r.pass_ms, r.gpu_ms_per_frame)).collect(),
        });
    }
    Ok(out)
}

/// Markdown of [`workgroups`]: per mode, one row per pass (and the frame), one column per shape,
/// median GPU ms and its ratio to 8×8. restir_temporal keeps 8×8 in every column.
pub fn workgroups_markdown(rows: &[WorkgroupBench]) -> String {
    let mut s = String::new();
    for b in rows {
        s += &format!("\n{} at {}×{}, {} interleaved frames per shape, median GPU ms (× 8×8):\n\n| pass |", b.mode, b.width, b.height, b.frames);
        for (shape, _, _) in &b.shapes {
            s += &format!(" {}×{} |", shape[0], shape[1]);
        }
        s += "\n|---|";
        s += &"---:|".repeat(b.shapes.len());
        s += "\n";
        let Some((_, first_passes, first_frame)) = b.shapes.first() else { continue };
        let cell = |ms: f64, base: f64| if base > 0.0 { format!(" {ms:.1} ({:.2}) |", ms / base) } else { format!(" {ms:.1} |") };
        for (pass, base) in first_passes {
            s += &format!("| {pass} |");
            for (_, passes, _) in &b.shapes {
                let ms = passes.iter().find(|(n, _)| n == pass).map(|p| p.1).unwrap_or(0.0);
                s += &cell(ms, *base);
            }
            s += "\n";
        }
        s += "| **frame** |";
        for (_, _, frame) in &b.shapes {
            s += &cell(*frame, *first_frame);
        }
        s += "\n";
    }
    s
}

/// One scene's rows of a `bench --modes --out` report: the still camera's and the moving one's.
pub struct ModesSection {
    pub scene: std::path::PathBuf,
    pub triangles: usize,
    pub rows: Vec<ModeBench>,
}

/// One scene's section of `bench --modes --out` at `size`, the still camera's rows then the moving
/// one's, from one load and upload of the scene; and the device's name.
pub fn modes_section(scene_path: &std::path::Path, size: (u32, u32), frames: u32, device: Option<usize>) -> Result<(ModesSection, String)> {
    let loaded = load_checked(scene_path, device)?;
    let (ctx, scene) = upload(&loaded, device)?;
    let mut rows = Vec::new();
    for moving in [false, true] {
        crate::errln!("bench --modes: {} {}", scene_path.display(), if moving { "moving" } else { "still" });
        rows.extend(modes_on(&ctx, &scene, scene_path, &[size], 100_000, 100_000, frames, moving, false, false)?);
    }
    let section = ModesSection { scene: scene_path.to_path_buf(), triangles: loaded.triangle_count(), rows };
    Ok((section, ctx.report.name.clone()))
}

/// The body of `bench --modes --out`'s `modes.md`: how it was made (command, sampling, device,
/// host, date), the ratios a reader looks for first (unbiased ReSTIR and RIS against uniform, per
/// scene and camera), then each scene's table.
pub fn modes_report(sections: &[ModesSection], frames: u32, device: &str, command: &str) -> String {
    let d = RenderSettings::default();
    let (mc, mn) = RenderSettings { mode: crate::settings::Mode::Restir, ..d.clone() }.moving_sampling();
    let mut s = format!(
        "Generated by `{command}` on {date} (UTC). 100k direct + 100k indirect VPLs, default settings: ReSTIR's passes fused \
         in pairs (`restir_initial_temporal`, `restir_spatial_shade`), {} presampled candidates, {} spatial neighbours, \
         M-cap {}; in a ReSTIR frame displayed alone with temporal history {mc} candidates and {mn} neighbours, its pixels \
         without history {} and {}. Two warm-up frames per mode, then {frames} frame{} per mode with the modes interleaved \
         frame by frame, so that the machine's drift hits all alike; medians. **still**: the scene's own camera, the G-buffer \
         traced once, accumulation on. **moving**: the camera goes along `scenes/<name>.path.json` and every frame is \
         displayed alone (progressive off): the G-buffer and temporal reprojection run every frame, as in the window while \
         flying. Compare ratios within a run; milliseconds drift between runs.\n\nDevice: {device}. Host: {}.\n\n",
        d.candidates,
        d.restir.spatial_neighbours,
        d.restir.mcap,
        d.candidates,
        d.restir.spatial_neighbours,
        if frames == 1 { "" } else { "s" },
        crate::eval::report::host_description(),
        date = crate::eval::report::utc_date(),
    );
    s += "| scene | size | camera | RIS × uniform | unbiased ReSTIR × uniform | biased ReSTIR × uniform |\n|---|---|---|---:|---:|---:|\n";
    for sec in sections {
        let name = sec.scene.file_stem().map(|n| n.to_string_lossy().to_string()).unwrap_or_default();
        let mut keys: Vec<(u32, u32, bool)> = sec.rows.iter().map(|r| (r.width, r.height, r.moving)).collect();
        keys.dedup();
        for (w, h, moving) in keys {
            let ratio = |label: &str| {
                sec.rows
                    .iter()
                    .find(|r| (r.width, r.height, r.moving) == (w, h, moving) && r.label.starts_with(label))
                    .map_or("–".to_string(), |r| format!("{:.2}", r.ratio_to_uniform))
            };
            s += &format!(
                "| {name} | {w}×{h} | {} | {} | {} | {} |\n",
                if moving { "moving" } else { "still" },
                ratio("ris"),
                ratio("restir unbiased, unshadowed"),
                ratio("restir biased")
            );
        }
    }
    for sec in sections {
        s += &format!("\n## {} ({} triangles)\n\n{}", sec.scene.display(), sec.triangles, modes_markdown(&sec.rows));
    }
    s
}

/// Milliseconds to three significant digits (two below 0.01 ms): lavapipe's frames take 100 ms, a GPU's 0.2 ms,
/// which one decimal showed as "0.2" and "0.0" (an H100's table at stop 45).
fn ms_text(ms: f64) -> String {
    match ms.abs() {
        m if m >= 100.0 => format!("{ms:.0}"),
        m if m >= 10.0 => format!("{ms:.1}"),
        m if m >= 1.0 => format!("{ms:.2}"),
        m if m >= 0.1 => format!("{ms:.3}"),
        _ => format!("{ms:.4}"),
    }
}

/// Markdown table of [`modes`]: one row per mode and size.
pub fn modes_markdown(rows: &[ModeBench]) -> String {
    let mut s = String::from(
        "| size | camera | mode | GPU ms / frame | × uniform | rays / pixel | per pass (GPU ms) |\n|---|---|---|---:|---:|---:|---|\n",
    );
    for r in rows {
        let passes: Vec<String> = r.pass_ms.iter().map(|(n, ms)| format!("{n} {}", ms_text(*ms))).collect();
        s += &format!(
            "| {}×{} | {} | {} | {} | {:.2} | {:.2} | {} |\n",
            r.width,
            r.height,
            if r.moving { "moving" } else { "still" },
            r.label,
            ms_text(r.gpu_ms_per_frame),
            r.ratio_to_uniform,
            r.rays_per_pixel_total,
            passes.join(", ")
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn milliseconds_keep_three_significant_digits() {
        let texts: Vec<String> = [158.4, 56.04, 3.456, 0.2414, 0.0042, 0.0].into_iter().map(ms_text).collect();
        assert_eq!(texts, ["158", "56.0", "3.46", "0.241", "0.0042", "0.0000"]);
    }

    /// A path from the origin at frame 0 to (x, 0, 0) at frame `last`, looking down +z.
    fn straight_path(last: u64, x: f32) -> CameraPath {
        CameraPath::from_json(&format!(
            r#"{{"keyframes": [{{"frame": 0, "eye": [0, 0, 0], "target": [0, 0, 1], "fov": 40}},
                              {{"frame": {last}, "eye": [{x}, 0, 0], "target": [{x}, 0, 1], "fov": 40}}]}}"#
        ))
        .expect("a valid path")
    }

    /// Every timed frame moves: it differs from the one before (the first from the warm-up at the
    /// path's start), also past the path's last keyframe, and stays on the path.
    #[test]
    fn moving_camera_never_stands_still() {
        let path = straight_path(5, 5.0);
        let mut previous = path.at(0.0).position;
        for f in 0..40 {
            let p = moving_camera(&path, f).position;
            assert!((p - previous).length() > 0.5, "frame {f} stands at {p} like the one before");
            assert!(p.x >= 0.0 && p.x <= 5.0 && p.y == 0.0, "frame {f} at {p} is off the path");
            previous = p;
        }
    }

    /// A path spanning 2^31 frames or more: twice its span wrapped u32 to 0 and the remainder
    /// divided by zero (bench --modes --moving panicked).
    #[test]
    fn moving_camera_takes_a_path_of_any_span() {
        let path = straight_path(1 << 31, 8.0);
        for f in [0, 1, 1000, u32::MAX] {
            let p = moving_camera(&path, f).position;
            assert!(p.is_finite() && p.x >= 0.0 && p.x <= 8.0, "frame {f} at {p}");
        }
    }

    /// One column per shape, one row per pass of the first shape plus the frame, each cell the
    /// median and its ratio to the first shape; a pass missing from a shape shows 0.
    #[test]
    fn workgroup_table_has_a_ratio_per_shape() {
        let pass = |a: f64, b: f64| vec![("vpl_shade".to_string(), a), ("restir_temporal".to_string(), b)];
        let rows = [WorkgroupBench {
            mode: "restir".into(),
            width: 64,
            height: 32,
            frames: 3,
            shapes: vec![([8, 8], pass(10.0, 4.0), 14.0), ([16, 4], pass(5.0, 4.0), 9.0), ([64, 1], vec![], 7.0)],
        }];
        let md = workgroups_markdown(&rows);
        assert!(md.contains("restir at 64×32, 3 interleaved frames"), "{md}");
        assert!(md.contains("| pass | 8×8 | 16×4 | 64×1 |\n|---|---:|---:|---:|\n"), "{md}");
        assert!(md.contains("| vpl_shade | 10.0 (1.00) | 5.0 (0.50) | 0.0 (0.00) |"), "{md}");
        assert!(md.contains("| restir_temporal | 4.0 (1.00) | 4.0 (1.00) | 0.0 (0.00) |"), "{md}");
        assert!(md.contains("| **frame** | 14.0 (1.00) | 9.0 (0.64) | 7.0 (0.50) |"), "{md}");
    }
}
