//! Headless runs: render N frames, write EXR/PNG/summary, return the images for callers (tests).

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context as _, Result};
use serde::Serialize;

use crate::camera::{Camera, CameraPath};
use crate::output::{stage_exr, stage_png, write_exr, TimingStats};
use crate::renderer::{Renderer, VplSummary};
use crate::scene::Scene;
use crate::scene_gpu::SceneGpu;
use crate::settings::RenderSettings;
use crate::vk::{Context, ContextOptions, DeviceReport};

/// Everything `summary.json` holds.
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    pub settings: RenderSettings,
    pub device: DeviceReport,
    pub validation_layer: bool,
    pub validation_errors: u64,
    pub scene: SceneSummary,
    /// The camera of the last frame.
    pub camera: Camera,
    /// Frames rendered.
    pub frames: u32,
    /// Frames in the final image's accumulation (fewer than `frames` when the camera or a setting
    /// changed during the run).
    pub accumulated_frames: u32,
    /// GPU time per pass over all frames where it ran (ms).
    pub pass_ms: BTreeMap<String, TimingStats>,
    /// GPU time of each pass's first dispatch (ms): on a driver that compiles a shader when it is
    /// first dispatched (lavapipe) with a cold shader cache, mostly the compilation.
    pub pass_first_ms: BTreeMap<String, f64>,
    /// GPU time per pass over the frames where it ran after its first (ms; count 0 for a pass
    /// that ran once): the steady cost, with no compilation in it.
    pub pass_ms_after_first: BTreeMap<String, TimingStats>,
    /// Sum of the pass times of each frame (ms).
    pub gpu_ms_per_frame: TimingStats,
    /// Of those, the first frame's (ms), which holds most shader compilation ([`Self::pass_first_ms`]).
    pub gpu_ms_first_frame: f64,
    /// Wall-clock time per frame including submission and waiting (ms).
    pub wall_ms_per_frame: TimingStats,
    /// Rays per pixel per frame (primary + sampling passes).
    pub rays_per_pixel: TimingStats,
    /// Rays per pixel per frame, by the pass that traced them (primary rays under "gbuffer"), over
    /// all frames (0 where a pass traced nothing), so the passes' means add up to the whole's.
    pub rays_per_pixel_by_pass: BTreeMap<String, TimingStats>,
    /// The VPL shading setup (VPL modes only).
    pub vpl: Option<crate::renderer::VplSummary>,
    /// Samples that were NaN or infinite in any frame of the run (each replaced by 0 in the
    /// accumulation, so the images stay finite; any at all is a defect to report).
    pub nonfinite_samples: u64,
    /// The photon pass (run once before frame 0), when the run needed VPLs.
    pub photons: Option<crate::passes::PhotonStats>,
    pub total_seconds: f64,
    /// Windowed runs: the frames as the display showed them.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub displayed: Option<DisplayedFrames>,
    pub outputs: Vec<String>,
    pub warnings: Vec<String>,
}

/// How fast a window showed its frames: presents per second of wall time, the whole loop included
/// (camera, overlay, blit, present wait), against the renderer's own GPU and wall times above.
#[derive(Clone, Debug, Serialize)]
pub struct DisplayedFrames {
    pub present_mode: String,
    /// Frames timed (the first two, warm-up, are not).
    pub frames: u32,
    pub ms_per_frame: f64,
    pub fps: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct SceneSummary {
    pub path: String,
    pub triangles: usize,
    pub instances: usize,
    /// Instances merged into one world-space mesh (`--merge-blas`; 0 when not merged), and BLASes
    /// built in all.
    pub merged_instances: usize,
    pub blases: usize,
    pub meshes: usize,
    pub materials: usize,
    /// Lights drawn: area-light triangles and point lights, the added ones included (the name is
    /// kept for the summaries' readers; `point_lights` says how many of them are points).
    pub area_lights: usize,
    /// Of `area_lights`, the point lights (the scene's and the added ones).
    pub point_lights: usize,
    /// Point lights added in the window (L).
    pub added_point_lights: usize,
    /// Σ Φ of the area lights, per channel (W).
    pub light_power: [f64; 3],
    pub upload_and_build_ms: f64,
}

/// What a headless run produced.
pub struct RunOutput {
    pub width: u32,
    pub height: u32,
    /// Mean over the frames of the last accumulation (all of them unless the camera or a setting
    /// changed, or frames are displayed alone), row 0 at the top.
    pub mean: Vec<[f32; 3]>,
    /// Per-pixel sample variance over the frames.
    pub variance: Vec<[f32; 3]>,
    pub summary: Summary,
}

/// The files every run writes to `--out` ([`finish_run`]).
pub const RUN_OUTPUT_FILES: [&str; 3] = ["final.exr", "final.png", "summary.json"];

/// The file `--save-every` writes to `--out` after frame `frame` (1-based).
pub fn snapshot_file(frame: u32) -> String {
    format!("accum_{frame:04}.exr")
}

/// The frame of a `--save-every` snapshot's file name ([`snapshot_file`]), None for any other name.
pub fn snapshot_frame(name: &str) -> Option<u32> {
    let digits = name.strip_prefix("accum_")?.strip_suffix(".exr")?;
    let frame: u32 = digits.bytes().all(|b| b.is_ascii_digit()).then(|| digits.parse().ok()).flatten()?;
    // Exactly as the program names it (accum_00001.exr is not one).
    (snapshot_file(frame) == name).then_some(frame)
}

/// The `--save-every` snapshots in `dir`, as an earlier run may have left them: entries named
/// exactly as the program names them ([`snapshot_frame`]) that are OpenEXR files, or directories
/// (`true`) in such a place. An unlisted directory has none.
fn snapshots_in(dir: &std::path::Path) -> Result<Vec<(std::path::PathBuf, u32, bool)>> {
    let entries = std::fs::read_dir(dir).with_context(|| format!("--out {}: cannot list the directory", dir.display()))?;
    Ok(entries
        .filter_map(|e| e.ok())
        .filter_map(|entry| {
            let frame = entry.file_name().to_str().and_then(snapshot_frame)?;
            let path = entry.path();
            let is_dir = std::fs::symlink_metadata(&path).is_ok_and(|m| m.is_dir());
            (is_dir || crate::output::is_exr_file(&path)).then_some((path, frame, is_dir))
        })
        .collect())
}

/// Before a run with `--save-every`: removes an earlier run's snapshots from `dir` (a series that
/// mixed two runs, accum_0003 and accum_0004 of a longer one beside this run's, misled a script
/// reading them all): files named as the program names them that are OpenEXR files; anything else
/// is left. Refuses a directory in the place of a snapshot this run writes (found only when that
/// frame was reached). Returns the files removed.
fn remove_earlier_snapshots(dir: &std::path::Path, settings: &RenderSettings) -> Result<usize> {
    if settings.save_every == 0 {
        return Ok(0);
    }
    let mut removed = 0;
    for (path, frame, is_dir) in snapshots_in(dir)? {
        if is_dir {
            let written = frame > 0 && frame <= settings.frames && frame % settings.save_every == 0;
            let name = path.file_name().unwrap_or_default().to_string_lossy();
            anyhow::ensure!(!written, "--out {}: {name} is a directory, where --save-every writes frame {frame}'s snapshot", dir.display());
            continue;
        }
        std::fs::remove_file(&path).with_context(|| format!("--out {}: removing an earlier run's snapshot {}", dir.display(), path.display()))?;
        removed += 1;
    }
    Ok(removed)
}

/// An earlier run's outputs in `dir` that this run leaves as they are: `--save-every` snapshots
/// when it takes none, a `passes/` dump when it dumps none.
fn earlier_outputs_left(dir: &std::path::Path, settings: &RenderSettings, dumps: bool) -> Vec<String> {
    let mut out = Vec::new();
    if settings.save_every == 0 {
        let snapshots = snapshots_in(dir).map(|s| s.iter().filter(|(_, _, is_dir)| !is_dir).count()).unwrap_or(0);
        if snapshots > 0 {
            out.push(format!(
                "--out {}: {snapshots} snapshot(s) accum_NNNN.exr of an earlier run are left there; this run writes none (no --save-every)",
                dir.display()
            ));
        }
    }
    if !dumps && dir.join("passes").join("index.html").exists() {
        out.push(format!("--out {}: passes/ holds an earlier run's pass dumps; this run dumps none (no --dump-passes)", dir.display()));
    }
    out
}

/// Refuses a run whose outputs would overwrite one of its inputs: the scene, the files it reads
/// (`scene_files`: external buffers and images), the camera path or the window's `--reference`, under `--out`'s fixed names
/// (and `--save-every`'s snapshots) or as `--dump-vpls`. Checked once the scene is loaded, before
/// any frame (`RenderSettings::validate` checks `--dump-vpls` against the scene and the camera path
/// before anything is read).
pub fn check_outputs_spare_inputs(settings: &RenderSettings, scene_files: &[std::path::PathBuf], reference: Option<&std::path::Path>) -> Result<()> {
    let mut inputs: Vec<(&str, &std::path::Path)> = vec![("the scene", settings.scene.as_path())];
    inputs.extend(scene_files.iter().map(|p| ("a file the scene reads", p.as_path())));
    inputs.extend(settings.camera_path.as_deref().map(|p| ("the --camera-path", p)));
    // The window's split-screen reference (--reference out/final.exr was overwritten by Enter).
    inputs.extend(reference.map(|p| ("the --reference", p)));
    for (what, input) in inputs {
        if let Some(dir) = &settings.out_dir {
            // Every fixed name, not only the input's own: out/final.png as a link to the scene
            // had the scene overwritten. Snapshots by the input's name: a run with --save-every
            // writes (and first removes) every accum_NNNN.exr there.
            let name = input.file_name().and_then(|n| n.to_str()).unwrap_or_default();
            let snapshot = (settings.save_every > 0 && snapshot_frame(name).is_some()).then_some(name);
            for written in RUN_OUTPUT_FILES.into_iter().chain(snapshot) {
                if crate::output::same_file(&dir.join(written), input) {
                    anyhow::bail!(
                        "--out {}: the run writes {written} there, which is {what} ({}); choose another --out",
                        dir.display(),
                        input.display()
                    );
                }
            }
        }
        if let Some(ply) = &settings.dump_vpls {
            if crate::output::same_file(ply, input) {
                anyhow::bail!("--dump-vpls {}: is also {what}; write the VPLs to another file", ply.display());
            }
        }
    }
    Ok(())
}

/// Ends a pass dump in `dir` (`--out/passes`): the VPLs and the inspector page over `dumped`,
/// their paths added to `outputs`. Returns the page's path.
fn finish_dump(renderer: &Renderer, dir: &std::path::Path, dumped: &[crate::dump::DumpedFrame], outputs: &mut Vec<String>) -> Result<std::path::PathBuf> {
    if let Some(vpls) = renderer.read_vpls()? {
        let ply = dir.join("vpls.ply");
        crate::ply::write_vpls(&ply, &vpls, renderer.scene().info.origin).context("--dump-passes: the VPLs beside the pass inspector")?;
        outputs.push(ply.display().to_string());
    }
    let page = crate::dump::write_inspector(dir, dumped)?;
    outputs.push(page.display().to_string());
    Ok(page)
}

/// Loads and uploads the scene, renders `settings.frames` frames and writes the outputs to
/// `settings.out_dir` (when set).
pub fn run(settings: &RenderSettings) -> Result<RunOutput> {
    run_noting(settings, Vec::new())
}

/// [`run`], with warnings the caller has already printed (the command line's: flags the mode
/// never reads) kept in the summary's `warnings` ahead of the run's own.
pub fn run_noting(settings: &RenderSettings, noted: Vec<String>) -> Result<RunOutput> {
    settings.validate()?;
    let start = Instant::now();
    let range = || crate::vk::context::storage_buffer_range(settings.device_index, settings.tracing);
    let scene = Scene::load_for_device(&settings.scene, settings.textures, &range)?;
    let ctx = Arc::new(Context::new(&ContextOptions {
        validate: settings.validate,
        device_index: settings.device_index,
        tracing: settings.tracing,
        ..Default::default()
    })?);
    let scene = Arc::new(SceneGpu::new(&ctx, &scene, settings.textures, settings.merge_blas).context("uploading the scene")?);
    run_with_noting(ctx, scene, settings, start, noted)
}

/// Says, when a run that wrote `--save-every` snapshots ends in an error before its final files
/// are in place, that the folder now mixes two runs: this one's snapshots beside an earlier run's
/// final.exr, final.png and summary.json (a script took them for one run's).
struct FailedRunNotice {
    dir: Option<std::path::PathBuf>,
    snapshots: u32,
    finished: bool,
}

impl Drop for FailedRunNotice {
    fn drop(&mut self) {
        let Some(dir) = self.dir.as_ref().filter(|_| !self.finished && self.snapshots > 0) else {
            return;
        };
        let earlier = RUN_OUTPUT_FILES.iter().filter(|f| dir.join(f).exists()).copied().collect::<Vec<_>>();
        let beside = if earlier.is_empty() { String::new() } else { format!(", beside {} of an earlier run", earlier.join(", ")) };
        log::warn!(
            "--out {}: this failed run's {} --save-every snapshot(s) accum_NNNN.exr are there{beside}",
            dir.display(),
            self.snapshots
        );
    }
}

/// Prints a warning now and keeps it for the summary's `warnings`.
fn warn_and_keep(warnings: &mut Vec<String>, w: String) {
    log::warn!("{w}");
    warnings.push(w);
}

/// As [`run`], with a context and an uploaded scene the caller already has.
pub fn run_with(ctx: Arc<Context>, scene: Arc<SceneGpu>, settings: &RenderSettings, start: Instant) -> Result<RunOutput> {
    run_with_noting(ctx, scene, settings, start, Vec::new())
}

/// [`run_with`], keeping `noted` as [`run_noting`] does.
fn run_with_noting(ctx: Arc<Context>, scene: Arc<SceneGpu>, settings: &RenderSettings, start: Instant, noted: Vec<String>) -> Result<RunOutput> {
    check_outputs_spare_inputs(settings, &scene.info.files, None)?;
    let mut warnings = noted;
    warnings.extend(scene.info.warnings.iter().cloned());
    if !scene.has_emitters() {
        warn_and_keep(&mut warnings, format!("{}: the scene has no emitters; the image will be black", scene.info.path.display()));
    }
    if let Some(w) = Renderer::vpl_radius_warning(settings, &scene).filter(|_| settings.view == crate::settings::View::Vpls) {
        warn_and_keep(&mut warnings, w);
    }
    if let Some(dir) = &settings.out_dir {
        crate::output::prepare_output_dir("--out", dir)?;
        // Checked before the frames, not after them.
        for name in RUN_OUTPUT_FILES {
            crate::output::check_writable(&dir.join(name)).with_context(|| format!("--out {}", dir.display()))?;
        }
        if settings.dump_passes.is_some() {
            crate::dump::check_dump_dir(&dir.join("passes"))?;
        }
    }
    // Read before the renderer's set-up (photons, pipelines), so that a bad file fails at once.
    // In the renderer's coordinates (the scene may have been recentred: Scene::origin).
    let path = settings.camera_path.as_deref().map(|p| CameraPath::load(p).context("--camera-path")).transpose()?.map(|p| p.moved(-scene.info.origin));
    let mut renderer = Renderer::new(ctx.clone(), scene.clone(), settings.clone())?;
    let camera_at = |f: u32| match &path {
        Some(p) => p.at(f as f32),
        None => Camera::initial(&scene.info, settings.camera.as_ref()),
    };
    let camera = camera_at(0);
    // (The device was logged when it was chosen.)
    // In the file's coordinates, as --eye takes them (the scene may have been moved).
    log::info!("camera ({}): {}", camera.source, camera.moved(scene.info.origin).describe());
    log::info!(
        "scene: {} triangles, {} instances ({} merged into one mesh, {} BLASes), {} lights, built in {:.1} ms",
        scene.triangle_count,
        scene.instance_count,
        scene.merged_instances,
        scene.blas_count,
        scene.lights.lights.len(),
        scene.build_ms
    );
    let mut outputs = Vec::new();
    let dump = settings.dump_passes_selection()?;
    if let (Some(_), Some(dir)) = (&dump, &settings.out_dir) {
        crate::dump::remove_earlier_dumps(&dir.join("passes"))?;
    }
    // After the set-up that can fail (the camera path, the renderer), before the first frame.
    if let Some(dir) = &settings.out_dir {
        let removed = remove_earlier_snapshots(dir, settings)?;
        if removed > 0 {
            warn_and_keep(&mut warnings, format!("--out {}: removed {removed} --save-every snapshot(s) of an earlier run", dir.display()));
        }
        // What an earlier run left that this one neither writes nor removes, said (not removed:
        // this run did not ask for such files), so that it is not read as this run's.
        for w in earlier_outputs_left(dir, settings, dump.is_some()) {
            warn_and_keep(&mut warnings, w);
        }
    }
    if let Some(path) = &settings.dump_vpls {
        let vpls = renderer.read_vpls()?.unwrap_or_default();
        crate::ply::write_vpls(path, &vpls, scene.info.origin).context("--dump-vpls")?;
        outputs.push(path.display().to_string());
    }
    let progress = Progress::new(settings.progress, settings.frames as u64);
    let mut dumped = Vec::new();
    let mut readout_budget = crate::dump::ReadoutBudget::default();
    let mut renderdoc = settings.renderdoc_capture.map(|_| crate::vk::renderdoc::Capturer::attach(&ctx));
    if let Some(rd) = &renderdoc {
        if !rd.attached() {
            warn_and_keep(&mut warnings, format!("--renderdoc-capture: {}", crate::vk::renderdoc::HOW_TO_CAPTURE));
        }
    }
    // Frames whose passes ran apart to be captured, where the others run fused.
    let mut captured_frames = 0u32;
    let mut failed_run = FailedRunNotice { dir: settings.out_dir.clone(), snapshots: 0, finished: false };
    for f in 0..settings.frames {
        let capture_this = settings.renderdoc_capture == Some(f);
        if capture_this {
            // Everything earlier is complete, so the capture holds this frame's submission alone.
            renderer.complete_all()?;
            if let Some(rd) = &mut renderdoc {
                rd.start();
            }
        }
        let last = f + 1 == settings.frames;
        let preview = last && settings.out_dir.is_some();
        let dump_this = dump.as_ref().is_some_and(|d| d.contains(f, settings.frames));
        if dump_this || settings.check_finite {
            let (stats, captured) = renderer.render_frame_captured(&camera_at(f), preview)?;
            // Counted where the capture kept a pair apart that would have run fused (not where
            // nothing could fuse: --temporal off and no spatial reuse, a reservoir view).
            if renderer.last_plan().is_some_and(|p| p.kept_apart_for_capture()) {
                captured_frames += 1;
            }
            let finite = if settings.check_finite { crate::dump::check_finite(f, &captured) } else { Ok(()) };
            // With --dump-passes the frame --check-finite stops at is dumped whatever the
            // selection: it is the one to look at (the run stopped with the earlier dumps removed
            // and nothing in their place).
            let dump_failed = finite.is_err() && dump.is_some();
            let mut dump_frame = || -> Result<()> {
                if let (true, Some(dir)) = (dump_this || dump_failed, &settings.out_dir) {
                    let plan = renderer.last_plan().context("a frame was just recorded")?.clone();
                    let variance = Some(renderer.read_variance()?);
                    let dir = dir.join("passes");
                    dumped.push(crate::dump::write_frame(&dir, f, settings.width, settings.height, settings, &plan, &stats, &captured, variance, renderer.log(), &mut readout_budget)?);
                }
                Ok(())
            };
            let dumped_ok = dump_frame();
            if let Err(e) = finite {
                // The non-finite values are what the user needs to read: a failed dump write (a
                // full disk) is said after them, not instead of them.
                if let Err(w) = dumped_ok {
                    return Err(e.context(format!("dumping frame {f} failed too ({w:#})")));
                }
                if let (true, Some(dir)) = (dump_failed, &settings.out_dir) {
                    return match finish_dump(&renderer, &dir.join("passes"), &dumped, &mut Vec::new()) {
                        Ok(page) => Err(e.context(format!("frame {f} is dumped in {}", page.display()))),
                        Err(w) => Err(e.context(format!("writing the pass inspector failed too ({w:#})"))),
                    };
                }
                return Err(e);
            }
            dumped_ok?;
        } else {
            renderer.render_frame(&camera_at(f), preview)?;
        }
        if capture_this {
            if let Some(rd) = &mut renderdoc {
                if rd.end() {
                    log::info!("RenderDoc: frame {f} captured");
                }
            }
        }
        if let Some(dir) = &settings.out_dir {
            if settings.save_every > 0 && (f + 1) % settings.save_every == 0 {
                let path = dir.join(snapshot_file(f + 1));
                write_exr(&path, settings.width, settings.height, &renderer.read_mean()?)?;
                failed_run.snapshots += 1;
                outputs.push(path.display().to_string());
            }
        }
        progress.tick();
    }
    progress.finish();
    if captured_frames > 0 {
        // The summary's settings say fuse_passes (what the other frames do); its pass timings
        // list these frames' passes apart.
        let why = if settings.check_finite { "--check-finite" } else { "--dump-passes" };
        let w = format!(
            "{why}: {captured_frames} of {} frame(s) ran their passes apart, to copy out each pass's output; the summary's \
             fuse_passes says what the other frames run",
            settings.frames
        );
        warn_and_keep(&mut warnings, w);
    }
    if let (false, Some(dir)) = (dumped.is_empty(), &settings.out_dir) {
        finish_dump(&renderer, &dir.join("passes"), &dumped, &mut outputs)?;
    }
    let summary = finish_run(&ctx, &scene, &mut renderer, settings.frames, Some(settings.frames), outputs, warnings, start, None)?;
    failed_run.finished = true;
    let mean = renderer.read_mean()?;
    let variance = renderer.read_variance()?;
    Ok(RunOutput { width: settings.width, height: settings.height, mean, variance, summary })
}

/// What every run ends with, headless or windowed: final.exr and final.png (when the settings have
/// an output directory; the last frame must have been rendered with a preview), and the summary,
/// written as summary.json beside them. `frames`: frames rendered in the run; `asked`: the frames
/// it was set to render, None for a window without `--frames` (it renders until closed), whose
/// summary then gives `settings.frames` as the frames rendered, not the flag's headless default.
#[allow(clippy::too_many_arguments)]
pub fn finish_run(
    ctx: &Context,
    scene: &SceneGpu,
    renderer: &mut Renderer,
    frames: u32,
    asked: Option<u32>,
    mut outputs: Vec<String>,
    mut warnings: Vec<String>,
    start: Instant,
    displayed: Option<DisplayedFrames>,
) -> Result<Summary> {
    renderer.complete_all()?;
    let mut settings = renderer.settings().clone();
    settings.frames = asked.unwrap_or(frames);
    // The three files are staged and put in place together at the end: a write that fails (a full
    // disk) leaves an earlier run's set whole, not its summary beside this run's EXR.
    let mut staged = Vec::new();
    if let Some(dir) = &settings.out_dir {
        std::fs::create_dir_all(dir).with_context(|| format!("--out {}: cannot create the directory", dir.display()))?;
        let exr = dir.join("final.exr");
        staged.push(stage_exr(&exr, settings.width, settings.height, &renderer.read_mean()?)?);
        let png = dir.join("final.png");
        staged.push(stage_png(&png, settings.width, settings.height, &renderer.read_preview()?)?);
        outputs.insert(0, png.display().to_string());
        outputs.insert(0, exr.display().to_string());
    }
    let validation_errors = ctx.validation_errors();
    if validation_errors > 0 {
        let w = format!(
            "{validation_errors} Vulkan validation error(s); first: {}",
            ctx.first_validation_error().unwrap_or_default()
        );
        warnings.push(w);
    }
    if renderer.nonfinite_samples_total() > 0 {
        warnings.push(format!("{} non-finite samples were replaced by 0", renderer.nonfinite_samples_total()));
    }
    // The photon pass said so on stderr; the summary keeps it too, the window's as well (a closed
    // box far from the origin had 0 indirect VPLs of 100000 and an empty `warnings`).
    if let Some(w) = renderer.photon_stats().and_then(|p| crate::passes::photon_emit::indirect_shortfall(settings.photon_settings().indirect, p.indirect_vpls, p.paths)) {
        warnings.push(w);
    }
    // The set-up's own (the device or the VPL set made a setting moot), said on stderr then.
    for w in renderer.setup_warnings() {
        if !warnings.contains(&w) {
            warnings.push(w);
        }
    }
    let log = renderer.log();
    let info = &scene.info;
    let summary = Summary {
        device: ctx.report.clone(),
        validation_layer: ctx.validation_enabled,
        validation_errors,
        scene: SceneSummary {
            path: info.path.display().to_string(),
            triangles: scene.triangle_count,
            instances: scene.instance_count,
            merged_instances: scene.merged_instances,
            blases: scene.blas_count,
            meshes: info.meshes,
            materials: info.materials,
            area_lights: renderer.lights().lights.len(),
            point_lights: renderer.lights().lights.iter().filter(|l| l.flags & crate::gpu_types::LIGHT_POINT != 0).count(),
            light_power: renderer.lights().total_power,
            added_point_lights: renderer.extra_lights().len(),
            upload_and_build_ms: scene.build_ms,
        },
        // In the file's coordinates, as --eye takes them.
        camera: renderer.camera().unwrap_or_else(|| renderer.initial_camera()).moved(info.origin),
        frames,
        accumulated_frames: renderer.accumulated(),
        pass_ms: log.pass_stats(),
        pass_first_ms: log.first_pass_ms(),
        pass_ms_after_first: log.pass_stats_after_first(),
        gpu_ms_per_frame: log.gpu(),
        gpu_ms_first_frame: log.gpu_ms.first().copied().unwrap_or(0.0),
        wall_ms_per_frame: log.wall(),
        rays_per_pixel: log.rays_per_pixel(),
        rays_per_pixel_by_pass: log.rays_per_pixel_by_pass(),
        vpl: match renderer.vpl_summary() {
            Some(v) => Some(VplSummary { grid_cells_built: renderer.grid_cells_built()?, ..v }),
            None => None,
        },
        nonfinite_samples: renderer.nonfinite_samples_total(),
        photons: renderer.photon_stats().cloned(),
        total_seconds: start.elapsed().as_secs_f64(),
        displayed,
        outputs,
        warnings,
        settings,
    };
    if let Some(dir) = &summary.settings.out_dir {
        let path: PathBuf = dir.join("summary.json");
        let json = serde_json::to_string_pretty(&summary).context("serialising summary.json")?;
        staged.push(crate::output::stage(&path, |partial| Ok(std::fs::write(partial, json)?))?);
    }
    for file in staged {
        file.commit()?;
    }
    Ok(summary)
}

/// A progress bar on stderr that appears only on a terminal and only once a run passes one second.
struct Progress {
    bar: Option<indicatif::ProgressBar>,
    start: Instant,
    shown: std::cell::Cell<bool>,
}

impl Progress {
    fn new(enabled: bool, total: u64) -> Self {
        use std::io::IsTerminal;
        let bar = (enabled && std::io::stderr().is_terminal()).then(|| {
            let bar = indicatif::ProgressBar::with_draw_target(Some(total), indicatif::ProgressDrawTarget::hidden());
            if let Ok(style) = indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} frames  {elapsed} (eta {eta})") {
                bar.set_style(style);
            }
            bar
        });
        Self { bar, start: Instant::now(), shown: std::cell::Cell::new(false) }
    }

    fn tick(&self) {
        if let Some(bar) = &self.bar {
            if !self.shown.get() && self.start.elapsed() > Duration::from_secs(1) {
                bar.set_draw_target(indicatif::ProgressDrawTarget::stderr());
                self.shown.set(true);
            }
            bar.inc(1);
        }
    }

    fn finish(&self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
    }
}
