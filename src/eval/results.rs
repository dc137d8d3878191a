//! Run time against error: references (`restir-vpl reference`), error-versus-frames/time curves
//! (`restir-vpl bench --curves`) and the one-command `docs/results.md` (`restir-vpl results`).
//!
//! Protocol of a curve run (one scene, several modes, one or two references):
//! - All modes share one Vulkan device and are alive at once; their frames interleave (one frame of
//!   each mode per round) so that drift on a shared machine hits every mode alike.
//! - Each mode first renders [`WARMUP_FRAMES`] frames (shader compilation on lavapipe, and the
//!   ReSTIR history), then its accumulation restarts with the history kept
//!   ([`Renderer::reset_accumulation`]): ReSTIR is measured in its steady state, as a user at a
//!   still camera sees it.
//! - At each checkpoint t the accumulated mean is read back and compared with each reference;
//!   read-back and comparison are outside the timed region. Times are cumulative over the t frames:
//!   GPU time from timestamps (sum of the pass scopes) and wall time of `render_frame`.
//! - Each run has its own pixel seed (same VPL set), never the base seed the references used, and
//!   with `runs > 1` the RMSE is the root of the runs' mean squared error, the other errors and the
//!   times their means, and the bias carries its standard error over the runs.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use anyhow::{bail, Context as _, Result};

use crate::eval::compare::{compare, CompareOptions};
use crate::output::{RgbImage, TimingStats};
use crate::camera::Camera;
use crate::eval::reference::{make_reference, ReferenceMeta, ReferenceTarget};
use crate::renderer::Renderer;
use crate::eval::report::{self, CurvePoint, FrameTimeRow, Metric, OverRuns};
use crate::scene::Scene;
use crate::scene_gpu::SceneGpu;
use crate::settings::{Bias, Mode, RenderSettings, RestirSettings};
use crate::vk::Context;

/// One checkpoint's values over the runs (one mode, one reference).
#[derive(Default)]
struct CheckpointSums {
    rmse: OverRuns,
    relmse: OverRuns,
    mean_ratio: OverRuns,
    worst_share: OverRuns,
    gpu_ms: OverRuns,
    wall_ms: OverRuns,
    /// Only the runs that computed FLIP.
    flip: OverRuns,
}

/// Frames rendered (and discarded) by every mode before its accumulation starts.
pub const WARMUP_FRAMES: u32 = 2;

/// The checkpoints of the thesis's Table 2.
pub const DEFAULT_CHECKPOINTS: &[u32] = &[1, 2, 5, 10, 20];
/// The frame count of issue 12's goals (fireflies, bias, equal-time RMSE).
pub const GOAL_FRAMES: u32 = 20;
/// The curve label of `--mode restir` with default settings (unbiased, unshadowed targets).
pub const DEFAULT_MODE: &str = "restir-unbiased";

/// The reference `path` with at least `frames` frames (rendered, topped up or reused), logged.
fn cached_reference(
    ctx: &Arc<Context>,
    scene: &Arc<SceneGpu>,
    settings: &RenderSettings,
    path: &Path,
    frames: u32,
    log: &mut dyn FnMut(String),
) -> Result<(RgbImage, ReferenceMeta)> {
    let mut announce = |done: u32, total: u32| {
        if done == 1 {
            log(format!("{}: rendering {total} {} frames at {}x{}", path.display(), settings.mode.name(), settings.width, settings.height));
        }
    };
    let made = make_reference(ctx, scene, settings, path, ReferenceTarget::AtLeast { frames }, &mut announce)?;
    match made.rendered {
        None => log(format!("{}: reusing ({})", path.display(), made.meta.describe_frames())),
        Some((n, gpu_ms, wall_ms)) => log(format!(
            "{}: rendered {n} {} frames at {}x{} ({}), {:.1} s wall, {:.1} s GPU",
            path.display(),
            settings.mode.name(),
            settings.width,
            settings.height,
            made.meta.describe_frames(),
            wall_ms * 1e-3,
            gpu_ms * 1e-3
        )),
    }
    Ok((made.image, made.meta))
}

/// One sampling configuration measured by a curve run.
#[derive(Clone, Debug)]
pub struct CurveMode {
    /// Label in tables and plots ("uniform", "ris", "restir", "restir-unbiased", ...).
    pub label: String,
    pub mode: Mode,
    pub restir: RestirSettings,
}

/// The modes of the thesis (uniform, RIS, biased ReSTIR) plus our unbiased ReSTIR, with and
/// without visibility in the targets.
pub fn curve_modes(all: bool) -> Vec<CurveMode> {
    let restir = |bias, vis| RestirSettings { bias, initial_visibility: Some(vis), ..Default::default() };
    let mut v = vec![
        CurveMode { label: "uniform".into(), mode: Mode::Uniform, restir: RestirSettings::default() },
        CurveMode { label: "ris".into(), mode: Mode::Ris, restir: RestirSettings::default() },
        CurveMode { label: "restir".into(), mode: Mode::Restir, restir: restir(Bias::Biased, false) },
    ];
    if all {
        v.push(CurveMode { label: "restir-unbiased".into(), mode: Mode::Restir, restir: restir(Bias::Unbiased, false) });
        v.push(CurveMode { label: "restir-unbiased-vis".into(), mode: Mode::Restir, restir: restir(Bias::Unbiased, true) });
    }
    v
}

/// Measured error-versus-frames/time curves of one scene and the per-frame cost of each mode.
pub struct Curves {
    pub points: Vec<CurvePoint>,
    pub frame_times: Vec<FrameTimeRow>,
}

/// Runs every mode in `modes` on `scene` (the remaining settings from `base`, whose spatial radius
/// should already suit the image size) and records the error against each of `references` at
/// each of `checkpoints`. See the module docs for the protocol.
#[allow(clippy::too_many_arguments)]
pub fn curves(
    ctx: &Arc<Context>,
    scene: &Arc<SceneGpu>,
    scene_label: &str,
    base: &RenderSettings,
    modes: &[CurveMode],
    checkpoints: &[u32],
    references: &[(String, RgbImage)],
    runs: u32,
    compare_opts: &CompareOptions,
    log: &mut dyn FnMut(String),
) -> Result<Curves> {
    let mut checkpoints: Vec<u32> = checkpoints.iter().copied().filter(|&t| t > 0).collect();
    checkpoints.sort_unstable();
    checkpoints.dedup();
    let last = *checkpoints.last().context("no checkpoints (all were 0)")?;
    for (name, img) in references {
        if (img.width, img.height) != (base.width, base.height) {
            bail!(
                "reference '{name}' is {}x{}, the run renders {}x{}",
                img.width,
                img.height,
                base.width,
                base.height
            );
        }
    }
    let camera = Camera::initial(&scene.info, base.camera.as_ref());
    let mut renderers = Vec::new();
    for m in modes {
        let settings = RenderSettings { mode: m.mode, restir: m.restir, frames: last + WARMUP_FRAMES, ..base.clone() };
        renderers.push(Renderer::new(ctx.clone(), scene.clone(), settings).with_context(|| format!("mode {}", m.label))?);
    }
    // Sums over runs, keyed by (mode index, reference index, checkpoint index).
    let mut sums: BTreeMap<(usize, usize, usize), CheckpointSums> = BTreeMap::new();
    let mut frame_gpu: Vec<Vec<f64>> = vec![Vec::new(); modes.len()];
    let mut frame_wall: Vec<Vec<f64>> = vec![Vec::new(); modes.len()];
    let mut pass_ms: Vec<BTreeMap<String, Vec<f64>>> = vec![BTreeMap::new(); modes.len()];
    let mut rays: Vec<Vec<f64>> = vec![Vec::new(); modes.len()];
    for run in 0..runs {
        for r in renderers.iter_mut() {
            // Every run, the first too, draws pixel seeds other than the base seed: the VPL
            // reference is RIS rendered with the base seed from frame 0, and a run with it would
            // repeat the reference's own random numbers (its error came out up to 27 % too low).
            r.restart(crate::eval::run_seed(base.seed, run))?;
            for _ in 0..WARMUP_FRAMES {
                r.render_frame(&camera, false)?;
            }
            r.reset_accumulation()?;
        }
        let mut cum = vec![(0.0f64, 0.0f64); modes.len()];
        let mut next = 0usize;
        for t in 1..=last {
            for (i, r) in renderers.iter_mut().enumerate() {
                let s = r.render_frame(&camera, false)?;
                let gpu = s.gpu_ms();
                cum[i].0 += gpu;
                cum[i].1 += s.wall_ms;
                frame_gpu[i].push(gpu);
                frame_wall[i].push(s.wall_ms);
                for (name, ms) in s.pass_ms() {
                    pass_ms[i].entry(name.to_string()).or_default().push(ms);
                }
                rays[i].push(s.rays as f64 / r.pixels() as f64);
            }
            if checkpoints.get(next) == Some(&t) {
                for (i, r) in renderers.iter().enumerate() {
                    let img = RgbImage { width: base.width, height: base.height, pixels: r.read_mean()? };
                    for (k, (_, reference)) in references.iter().enumerate() {
                        let c = compare(&img, reference, compare_opts)?;
                        let e = sums.entry((i, k, next)).or_default();
                        e.rmse.add(c.rmse);
                        e.relmse.add(c.relmse);
                        e.mean_ratio.add(c.mean_ratio);
                        e.worst_share.add(c.worst_share);
                        e.gpu_ms.add(cum[i].0);
                        e.wall_ms.add(cum[i].1);
                        if let Some(f) = c.flip {
                            e.flip.add(f);
                        }
                    }
                }
                next += 1;
            }
        }
        log(format!("  {scene_label}: run {}/{runs} done", run + 1));
    }
    let mut points = Vec::new();
    for ((i, k, c), e) in &sums {
        points.push(CurvePoint {
            scene: scene_label.into(),
            mode: modes[*i].label.clone(),
            reference: references[*k].0.clone(),
            frames: checkpoints[*c],
            gpu_ms: e.gpu_ms.mean(),
            wall_ms: e.wall_ms.mean(),
            rmse: e.rmse.rms(),
            relmse: e.relmse.mean(),
            mean_ratio: e.mean_ratio.mean(),
            mean_ratio_se: e.mean_ratio.standard_error(),
            worst_share: e.worst_share.mean(),
            flip: (e.flip.count() > 0).then(|| e.flip.mean()),
        });
    }
    // Order: reference, mode (as given), frames.
    points.sort_by_key(|p| {
        (
            references.iter().position(|r| r.0 == p.reference),
            modes.iter().position(|m| m.label == p.mode),
            p.frames,
        )
    });
    let frame_times = modes
        .iter()
        .enumerate()
        .map(|(i, m)| FrameTimeRow {
            scene: scene_label.into(),
            mode: m.label.clone(),
            width: base.width,
            height: base.height,
            gpu_ms: TimingStats::of(&frame_gpu[i]).median,
            wall_ms: TimingStats::of(&frame_wall[i]).median,
            rays_per_pixel: TimingStats::of(&rays[i]).mean,
            pass_ms: pass_ms[i].iter().map(|(k, v)| (k.clone(), TimingStats::of(v).median)).collect(),
        })
        .collect();
    Ok(Curves { points, frame_times })
}

/// One scene of a results run.
#[derive(Clone, Debug)]
pub struct SceneSpec {
    pub path: PathBuf,
    pub width: u32,
    pub height: u32,
}

impl SceneSpec {
    pub fn label(&self) -> String {
        self.path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "scene".into())
    }

    /// Loads and uploads the scene once; every mode and reference of a study renders from it.
    pub fn upload(&self, ctx: &Arc<Context>) -> Result<Arc<SceneGpu>> {
        // Textures over the device's buffer range refused before they are decoded.
        let range = u64::from(ctx.properties.limits.max_storage_buffer_range);
        let scene = Scene::load_for_device(&self.path, true, &|| Some(range))?;
        Ok(Arc::new(SceneGpu::new(ctx, &scene, true, crate::vk::accel::MERGE_MAX_TRIANGLES).context("uploading the scene")?))
    }

    /// The settings every mode of a study starts from: this scene at this size, the study's VPL
    /// counts (the spatial radius is the renderer's default, which scales with the width).
    pub fn base_settings(&self, vpls: (u32, u32), validate: bool, device_index: Option<usize>) -> RenderSettings {
        RenderSettings {
            scene: self.path.clone(),
            width: self.width,
            height: self.height,
            vpls_direct: vpls.0,
            vpls_indirect: vpls.1,
            validate,
            device_index,
            ..Default::default()
        }
    }
}

/// The thesis's three scenes at its sizes (Cornell box 1280×1280, the others 1280×720), scaled.
pub fn thesis_scenes(root: &Path, scale: f64) -> Vec<SceneSpec> {
    let s = |name: &str, w: u32, h: u32| SceneSpec {
        path: root.join("scenes").join(name),
        width: ((w as f64 * scale).round() as u32).max(8),
        height: ((h as f64 * scale).round() as u32).max(8),
    };
    vec![
        s("cornell_box.gltf", 1280, 1280),
        s("living_room.gltf", 1280, 720),
        s("open_box_figure.gltf", 1280, 720),
    ]
}

/// Everything a results run needs.
#[derive(Clone, Debug)]
pub struct ResultsOptions {
    pub scenes: Vec<SceneSpec>,
    /// Directory for results.md (or curves.md), curves.csv, plots/ and references/.
    pub out_dir: PathBuf,
    /// Markdown file name inside `out_dir`.
    pub markdown_name: String,
    pub checkpoints: Vec<u32>,
    pub runs: u32,
    /// Frames of the path-traced ground truth and of the converged VPL reference (RIS).
    pub pt_reference_frames: u32,
    pub vpl_reference_frames: u32,
    /// Other VPL sets (photon seeds) rendered converged (RIS, `vpl_set_frames` frames each) to
    /// measure how far one set's answer strays from the VPL model's mean (0: none).
    pub vpl_sets: u32,
    pub vpl_set_frames: u32,
    pub vpls_direct: u32,
    pub vpls_indirect: u32,
    /// Measure the unbiased ReSTIR variants too.
    pub all_modes: bool,
    pub flip: bool,
    pub device_index: Option<usize>,
    pub validate: bool,
    /// The command line, quoted in the Markdown.
    pub command: String,
    /// A `--quick` run: its report says it is a smoke test.
    pub quick: bool,
    /// The moving-camera measurement (`bench --motion`) added as a section; its references go to
    /// `out_dir/references` with the others.
    pub motion: Option<crate::eval::motion::MotionOptions>,
}

impl ResultsOptions {
    /// The full run behind docs/results.md, at `scale` × the thesis's image sizes.
    pub fn full(root: &Path, scale: f64) -> Self {
        Self {
            scenes: thesis_scenes(root, scale),
            out_dir: root.join("docs"),
            markdown_name: "results.md".into(),
            // The thesis's checkpoints and 40, so that RIS's curve covers ReSTIR's 20-frame time.
            checkpoints: [DEFAULT_CHECKPOINTS, &[2 * GOAL_FRAMES]].concat(),
            runs: 3,
            pt_reference_frames: 1024,
            vpl_reference_frames: 1024,
            vpl_sets: 8,
            vpl_set_frames: 64,
            vpls_direct: 100_000,
            vpls_indirect: 100_000,
            all_modes: true,
            flip: true,
            device_index: None,
            validate: false,
            command: String::new(),
            quick: false,
            // Smaller than the curves' images: one path-traced reference per moving frame.
            motion: Some(crate::eval::motion::MotionOptions::full(root, scale * 0.8)),
        }
    }

    /// A smoke test of the whole pipeline in well under a minute on lavapipe.
    pub fn quick(root: &Path) -> Self {
        Self {
            scenes: thesis_scenes(root, 0.05),
            checkpoints: vec![1, 2, 5],
            runs: 1,
            pt_reference_frames: 16,
            vpl_reference_frames: 16,
            vpl_sets: 2,
            vpl_set_frames: 4,
            vpls_direct: 5_000,
            vpls_indirect: 5_000,
            all_modes: false,
            quick: true,
            motion: Some(crate::eval::motion::MotionOptions::quick(root)),
            ..Self::full(root, 0.05)
        }
    }
}

/// What a results run produced.
pub struct ResultsOutput {
    pub markdown: PathBuf,
    pub csv: PathBuf,
    pub frame_times_csv: PathBuf,
    /// The moving-camera section's numbers, when it ran.
    pub motion_csv: Option<PathBuf>,
    pub plots: Vec<PathBuf>,
    pub points: Vec<CurvePoint>,
    pub frame_times: Vec<FrameTimeRow>,
}

struct ReferenceInfo {
    scene: String,
    kind: &'static str,
    meta: ReferenceMeta,
    path: PathBuf,
}

/// The converged VPL answer against the path-traced one: the VPL model's own bias, if the
/// references are converged enough to show it.
struct ModelBias {
    scene: String,
    /// RMSE between the two references.
    rmse: f64,
    /// mean(vpl reference) / mean(pt reference).
    mean_ratio: f64,
    /// RMSE the two references' noise alone would give: √(noise_pt² + noise_vpl²).
    noise_rmse: Option<f64>,
    /// Standard error of the MSE between the references (the spread of the per-pixel, per-channel
    /// squared differences over their count).
    mse_se: f64,
    /// mean(vpl) / mean(pt) over other VPL sets: the VPL model's mean ratio, free of one set's own
    /// error.
    over_sets: Option<SetSpread>,
}

/// mean(image) / mean(pt reference) of converged VPL answers over independent VPL sets.
#[derive(Clone, Copy, Debug)]
pub struct SetSpread {
    pub sets: usize,
    pub mean_ratio: f64,
    /// Standard error of `mean_ratio` over the sets.
    pub se: f64,
    /// One set's standard deviation: how far a single set's answer strays.
    pub sd: f64,
}

/// Renders `opts.vpl_sets` VPL sets of `base` (each its own photon seed) converged with RIS and
/// measures mean(image) / mean(`pt`) over them (None for fewer than two sets).
fn vpl_set_spread(
    ctx: &Arc<Context>,
    scene: &Arc<SceneGpu>,
    base: &RenderSettings,
    pt: &RgbImage,
    opts: &ResultsOptions,
    log: &mut dyn FnMut(String),
) -> Result<Option<SetSpread>> {
    if opts.vpl_sets < 2 || opts.vpl_set_frames == 0 {
        return Ok(None);
    }
    let mut ratios = OverRuns::default();
    for k in 0..opts.vpl_sets {
        let settings = RenderSettings { mode: Mode::Ris, seed: crate::eval::run_seed(base.seed, k), ..base.clone() };
        let mut r = Renderer::new(ctx.clone(), scene.clone(), settings).with_context(|| format!("VPL set {}", k + 1))?;
        let camera = r.initial_camera();
        for _ in 0..opts.vpl_set_frames {
            r.render_frame(&camera, false)?;
        }
        let img = RgbImage { width: pt.width, height: pt.height, pixels: r.read_mean()? };
        ratios.add(compare(&img, pt, &CompareOptions { flip: false, ..Default::default() })?.mean_ratio);
    }
    let se = ratios.standard_error().expect("two sets or more");
    let spread = SetSpread { sets: ratios.count(), mean_ratio: ratios.mean(), se, sd: se * (ratios.count() as f64).sqrt() };
    log(format!(
        "  {} VPL sets: mean(vpl) / mean(pt) = {:.4} ± {:.4} (one set's sd {:.4})",
        spread.sets, spread.mean_ratio, spread.se, spread.sd
    ));
    Ok(Some(spread))
}

/// The standard error of the mean squared difference of two images (finite pixels only), from
/// the spread of the per-pixel squared differences: one value per pixel (its three channels'
/// mean), since a pixel's channels are far from independent (their differences correlate 0.6–0.8
/// in the Cornell box's references; counted as three samples, the error came out ~1.1× too small).
fn mse_standard_error(a: &RgbImage, b: &RgbImage) -> f64 {
    let mut d = OverRuns::default();
    a.pixels
        .iter()
        .zip(&b.pixels)
        .map(|(p, q)| (0..3).map(|c| (f64::from(p[c]) - f64::from(q[c])).powi(2)).sum::<f64>() / 3.0)
        .filter(|x| x.is_finite())
        .for_each(|x| d.add(x));
    d.standard_error().unwrap_or(f64::INFINITY)
}

/// `--checkpoints` as the curves take them: ascending, each once (the report listed `5,2,2` as
/// given, beside tables of 2 and 5).
pub fn sorted_checkpoints(given: &[u32]) -> Vec<u32> {
    let mut c = given.to_vec();
    c.sort_unstable();
    c.dedup();
    c
}

/// Renders (or reuses) the references, measures the curves of every scene and writes the Markdown
/// report, the CSVs and the plots under `opts.out_dir`.
pub fn run(ctx: &Arc<Context>, opts: &ResultsOptions, log: &mut dyn FnMut(String)) -> Result<ResultsOutput> {
    if opts.checkpoints.is_empty() || opts.runs == 0 {
        bail!("need at least one checkpoint and one run");
    }
    // The scenes before anything is created under OUT (a run from outside the repository made
    // OUT/plots and OUT/references, then failed on scenes/cornell_box.gltf).
    for spec in &opts.scenes {
        if !spec.path.is_file() {
            bail!("scene file '{}' not found: `results` renders the bundled scenes by their paths in the repository; run it from the repository's root", spec.path.display());
        }
    }
    let plots_dir = opts.out_dir.join("plots");
    let refs_dir = opts.out_dir.join("references");
    for d in [&opts.out_dir, &plots_dir, &refs_dir] {
        std::fs::create_dir_all(d).with_context(|| format!("creating {}", d.display()))?;
    }
    let mut all_points = Vec::new();
    let mut all_rows = Vec::new();
    let mut ref_infos = Vec::new();
    let mut model_bias = Vec::new();
    let started = Instant::now();
    for spec in &opts.scenes {
        let label = spec.label();
        let scene = spec.upload(ctx)?;
        let base = spec.base_settings((opts.vpls_direct, opts.vpls_indirect), opts.validate, opts.device_index);
        let size = format!("{}x{}", spec.width, spec.height);
        let pt_settings = RenderSettings { mode: Mode::Pt, ..base.clone() };
        let pt_path = refs_dir.join(format!("{label}_{size}_pt.exr"));
        let (pt_img, pt_meta) = cached_reference(ctx, &scene, &pt_settings, &pt_path, opts.pt_reference_frames, log)?;
        let vpl_settings = RenderSettings { mode: Mode::Ris, ..base.clone() };
        let vpl_path = refs_dir.join(format!("{label}_{size}_vpl.exr"));
        let (vpl_img, vpl_meta) =
            cached_reference(ctx, &scene, &vpl_settings, &vpl_path, opts.vpl_reference_frames, log)?;
        let agreement = compare(&vpl_img, &pt_img, &CompareOptions { flip: false, ..Default::default() })?;
        let over_sets = vpl_set_spread(ctx, &scene, &base, &pt_img, opts, log)?;
        model_bias.push(ModelBias {
            scene: label.clone(),
            rmse: agreement.rmse,
            mean_ratio: agreement.mean_ratio,
            noise_rmse: pt_meta.noise_mse.zip(vpl_meta.noise_mse).map(|(a, b)| (a + b).sqrt()),
            mse_se: mse_standard_error(&vpl_img, &pt_img),
            over_sets,
        });
        ref_infos.push(ReferenceInfo { scene: label.clone(), kind: "pt", meta: pt_meta, path: pt_path });
        ref_infos.push(ReferenceInfo { scene: label.clone(), kind: "vpl", meta: vpl_meta, path: vpl_path });
        log(format!("{label}: measuring curves at {size}"));
        let compare_opts = CompareOptions { flip: opts.flip, ..Default::default() };
        let c = curves(
            ctx,
            &scene,
            &label,
            &base,
            &curve_modes(opts.all_modes),
            &opts.checkpoints,
            &[("pt".into(), pt_img), ("vpl".into(), vpl_img)],
            opts.runs,
            &compare_opts,
            log,
        )?;
        all_points.extend(c.points);
        all_rows.extend(c.frame_times);
    }
    let csv = opts.out_dir.join("curves.csv");
    report::write_curves_csv(&csv, &all_points)?;
    let frame_times_csv = opts.out_dir.join("frame_times.csv");
    write_frame_times_csv(&frame_times_csv, &all_rows)?;
    let mut plots = Vec::new();
    for spec in &opts.scenes {
        let label = spec.label();
        for reference in ["pt", "vpl"] {
            let f = plots_dir.join(format!("{label}_{reference}_rmse_vs_frames.svg"));
            report::plot_error_vs_frames(&f, &all_points, &label, reference, Metric::Rmse)?;
            plots.push(f);
            let f = plots_dir.join(format!("{label}_{reference}_rmse_vs_time.svg"));
            report::plot_error_vs_time(&f, &all_points, &label, reference, Metric::Rmse)?;
            plots.push(f);
        }
    }
    let mut motion_section = None;
    let mut motion_csv = None;
    if let Some(m) = &opts.motion {
        let m = crate::eval::motion::MotionOptions {
            out_dir: opts.out_dir.clone(),
            validate: opts.validate,
            flip: opts.flip,
            ..m.clone()
        };
        log("moving camera: per displayed frame".into());
        let points = crate::eval::motion::run(ctx, &m, log)?;
        let files = crate::eval::motion::write_outputs(&opts.out_dir, &points)?;
        motion_section = Some(crate::eval::motion::section_markdown(&m, &points, &files.plots));
        motion_csv = Some(files.csv);
        plots.extend(files.plots);
    } else if opts.out_dir.join("motion.csv").exists() {
        // Not removed: `bench --motion --out` writes the same files beside its motion.md.
        log::warn!(
            "results --no-motion: {} and its plots (plots/*_motion_*.svg) are not this run's: they come from an earlier \
             `results` or `bench --motion` there, and this results.md does not link them",
            opts.out_dir.join("motion.csv").display()
        );
    }
    let markdown = opts.out_dir.join(&opts.markdown_name);
    let mut text = results_markdown(ctx, opts, &all_points, &all_rows, &ref_infos, &model_bias, started.elapsed().as_secs_f64());
    if let Some(section) = motion_section {
        text.push_str("\n## Moving camera: the error of every displayed frame (`bench --motion`)\n\n");
        text.push_str(&section);
        text.push_str("\nRaw numbers: `motion.csv` (scene, mode, measured frame from 0, at the path's frame + 1, GPU ms, RMSE, relMSE, FLIP).\n");
    }
    crate::output::write_text(&markdown, &text)?;
    Ok(ResultsOutput { markdown, csv, frame_times_csv, motion_csv, plots, points: all_points, frame_times: all_rows })
}

fn write_frame_times_csv(path: &Path, rows: &[FrameTimeRow]) -> Result<()> {
    let passes: std::collections::BTreeSet<&String> = rows.iter().flat_map(|r| r.pass_ms.keys()).collect();
    let mut s = String::from("scene,mode,width,height,gpu_ms,wall_ms,rays_per_pixel");
    for p in &passes {
        s.push_str(&format!(",{p}_ms"));
    }
    s.push('\n');
    for r in rows {
        s.push_str(&format!(
            "{},{},{},{},{:.4},{:.4},{:.4}",
            r.scene, r.mode, r.width, r.height, r.gpu_ms, r.wall_ms, r.rays_per_pixel
        ));
        for p in &passes {
            s.push_str(&r.pass_ms.get(*p).map(|v| format!(",{v:.4}")).unwrap_or_else(|| ",".into()));
        }
        s.push('\n');
    }
    std::fs::write(path, s).with_context(|| format!("writing {}", path.display()))
}

/// The CPU and core count of the machine that ran the study (the device may be a CPU renderer).
fn results_markdown(
    ctx: &Arc<Context>,
    opts: &ResultsOptions,
    points: &[CurvePoint],
    rows: &[FrameTimeRow],
    refs: &[ReferenceInfo],
    model_bias: &[ModelBias],
    seconds: f64,
) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let _ = writeln!(s, "# Run time against error\n");
    let _ = writeln!(
        s,
        "_Generated by `{}` on {} (UTC) in {:.0} s on **{}** ({}). Do not edit by hand: rerun the command._{}\n",
        opts.command,
        report::utc_date(),
        seconds,
        ctx.report.name,
        ctx.report.driver,
        if opts.quick {
            " **Quick run** (`--quick`): a smoke test of the pipeline at tiny sizes and counts, fewer modes and no \
             goals section, not a measurement."
        } else {
            ""
        }
    );
    let _ = writeln!(s, "Host: {}.\n", report::host_description());
    let sizes: Vec<String> =
        opts.scenes.iter().map(|s| format!("{} {}×{}", s.label(), s.width, s.height)).collect();
    let _ = writeln!(
        s,
        "Scenes and sizes: {}. VPLs: {} direct + {} indirect (photon paths). Checkpoints t = {:?} accumulated frames, \
         {} independent run(s) averaged (RMSE: the root of the runs' mean squared error; the other errors and the times: \
         their means; ± the standard error of the mean over the runs). Every mode first renders {WARMUP_FRAMES} warm-up frames (shader compilation, \
         ReSTIR history) that are not counted; then frames of all modes interleave so that machine drift hits them alike. \
         Times are cumulative over the t frames: GPU time from timestamps, wall time of the frame submissions \
         (read-back and error computation excluded).\n",
        sizes.join(", "),
        opts.vpls_direct,
        opts.vpls_indirect,
        opts.checkpoints,
        opts.runs
    );
    let _ = writeln!(
        s,
        "Modes: `uniform` (one uniformly chosen VPL per pixel), `ris` (32 candidates), `restir` (biased \
         spatiotemporal reuse as in the thesis: M-cap 20, 8 neighbours; spatial radius the renderer's default, {} px per \
         1280 px of width and at least {} px; the thesis had 20 px at 1280){}.\n",
        crate::settings::SPATIAL_RADIUS_AT_1280,
        crate::settings::MIN_SPATIAL_RADIUS,
        // (Only the modes measured: a quick run lists three, and the text named five.)
        if opts.all_modes {
            ", `restir-unbiased` (pairwise MIS, unshadowed targets) and `restir-unbiased-vis` (pairwise MIS, visibility in \
             the targets)"
        } else {
            ""
        }
    );
    let _ = writeln!(s, "## References\n");
    let _ = writeln!(
        s,
        "Two references per scene. **pt**: the path tracer (up to 8 bounces, next-event estimation + MIS) — the ground \
         truth; errors against it are the total error, including the VPL model's own bias (clamped Yuksel attenuation, \
         finite VPL set, bounce limit). **vpl**: the converged answer of the same VPL set (RIS, unbiased for it, accumulated \
         long) — errors against it are the sampling error alone. A reference is itself noisy; its estimated noise RMSE \
         (√(mean per-pixel variance / frames)) is listed: errors far above it are not masked by it.\n"
    );
    let _ = writeln!(s, "| scene | reference | mode | frames | est. noise RMSE | file |");
    let _ = writeln!(s, "|---|---|---|---:|---:|---|");
    for r in refs {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | `{}` |",
            r.scene,
            r.kind,
            r.meta.mode,
            r.meta.frames,
            r.meta.noise_mse.map(|m| report::fmt_sig3(m.sqrt())).unwrap_or_else(|| "—".into()),
            r.path.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default()
        );
    }
    let _ = writeln!(s);
    let _ = writeln!(
        s,
        "The VPL model's own bias (the converged VPL answer against the path-traced one). The MSE between the \
         references is the bias's plus their noise's; the bias is resolved where that MSE exceeds the noise's by more \
         than 4 standard errors of the MSE (from the spread of the per-pixel squared differences; the noise estimates, \
         from at least {} frames per pixel, are taken as exact), and its RMSE is then √(MSE − noise²). The VPL reference is \
         one VPL set, whose own error moves its mean: the last column is the same ratio over {} other VPL sets (photon \
         seeds), each converged with RIS over {} frames, ± its standard error over them, and one set's standard \
         deviation (sd). That column is the VPL model's mean ratio; the reference's column is one draw from around it.\n",
        opts.pt_reference_frames.min(opts.vpl_reference_frames),
        opts.vpl_sets,
        opts.vpl_set_frames
    );
    let _ = writeln!(s, "| scene | RMSE(vpl, pt) | noise alone | mean(vpl) / mean(pt) | verdict | mean(vpl) / mean(pt) over VPL sets |");
    let _ = writeln!(s, "|---|---:|---:|---:|---|---:|");
    for b in model_bias {
        let verdict = match b.noise_rmse {
            // Identical images (an RMSE of 0) made z NaN, printed as such.
            Some(_) if b.rmse == 0.0 => "not resolved (the images agree exactly)".into(),
            Some(n) => {
                let excess = b.rmse * b.rmse - n * n;
                let z = excess / b.mse_se;
                if z > 4.0 {
                    format!("VPL bias resolved: ≈ {} RMSE (MSE above the noise's by {z:.0} standard errors)", report::fmt_sig3(excess.sqrt()))
                } else {
                    format!("VPL bias not resolved (MSE above the noise's by {z:.1} standard errors)")
                }
            }
            None => "unknown (no noise estimate)".into(),
        };
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.4} | {verdict} | {} |",
            b.scene,
            report::fmt_sig3(b.rmse),
            b.noise_rmse.map(report::fmt_sig3).unwrap_or_else(|| "—".into()),
            b.mean_ratio,
            b.over_sets
                .map(|o| format!("{:.4} ± {:.4} (sd {:.4}, {} sets)", o.mean_ratio, o.se, o.sd, o.sets))
                .unwrap_or_else(|| "—".into())
        );
    }
    let _ = writeln!(s);
    let _ = writeln!(s, "## Bias at the last checkpoint\n");
    let _ = writeln!(
        s,
        "mean(image) / mean(reference) after the last checkpoint, averaged over the runs{}. Against the VPL reference an \
         unbiased mode tends to 1 (up to the noise of a few frames, which heavy-tailed modes have much of); biased ReSTIR \
         need not.\n",
        match opts.runs {
            1 => " (one run: no standard error)".to_string(),
            r => format!(
                ", ± its standard error over them (from {r} runs, {} degree{} of freedom{})",
                r - 1,
                if r == 2 { "" } else { "s" },
                if r < 6 { ": a rough one" } else { "" }
            ),
        }
    );
    let labels: Vec<String> = opts.scenes.iter().map(SceneSpec::label).collect();
    s.push_str(&report::bias_table_markdown(points, &labels));
    let _ = writeln!(s);
    if points.iter().any(|p| p.mode == DEFAULT_MODE) {
        let t_goal = GOAL_FRAMES.min(*opts.checkpoints.iter().max().unwrap_or(&1));
        let first = opts.checkpoints.iter().copied().min().unwrap_or(1);
        let _ = writeln!(s, "## Goals of the default mode\n");
        let _ = writeln!(
            s,
            "`--mode restir` with default settings (the `restir-unbiased` rows) against the path tracer, as issue 12 sets \
             them: fireflies (the worst 0.1 % of pixels' share of the squared error) at most 20 %, bias within ±1 %, and \
             an RMSE below RIS's at equal time after {first} and after {t_goal} frames on at least two of the three scenes. \
             Equal time: RIS's error within the wall time ReSTIR took for its t frames, interpolated along RIS's curve \
             (RIS fits more frames in that time, hence checkpoints past {t_goal}). The bias is a mean over the runs of \
             t frames each, so it carries their noise: ± is its standard error over the runs. The runs share the VPL \
             reference's VPL set, whose own error offsets their ratio to the path tracer (the model-bias table's sd), so \
             the bias over VPL sets is estimated as their ratio to that set's converged answer times the VPL model's \
             mean ratio over VPL sets (the table's last column), with the standard error of both; the mark compares \
             that estimate's mean alone.\n"
        );
        let model_ratio: Vec<(String, f64, f64)> =
            model_bias.iter().filter_map(|b| b.over_sets.map(|o| (b.scene.clone(), o.mean_ratio, o.se))).collect();
        s.push_str(&report::goals_markdown(points, &labels, &model_ratio, DEFAULT_MODE, "ris", t_goal, &[first, t_goal], 0.20, 0.01));
        let _ = writeln!(s);
    }
    let _ = writeln!(s, "## Frame times (thesis Table 1 shape)\n");
    let _ = writeln!(s, "Median per frame over all measured frames; `× uniform` is the ratio to the uniform mode measured in the same run.\n");
    s.push_str(&report::frame_time_table_markdown(rows));
    let _ = writeln!(s);
    for spec in &opts.scenes {
        let label = spec.label();
        let _ = writeln!(s, "## {label} ({}×{})\n", spec.width, spec.height);
        for reference in ["pt", "vpl"] {
            let _ = writeln!(s, "### RMSE against the {} (thesis Table 2 shape)\n", report::reference_label(reference));
            s.push_str(&report::error_table_markdown(points, &label, reference, Metric::Rmse));
            let _ = writeln!(s);
            let budgets = report::suggest_budgets_ms(points, &label, reference);
            if !budgets.is_empty() {
                let _ = writeln!(s, "Equal time (wall ms budget; RMSE reached within it):\n");
                s.push_str(&report::equal_time_table_markdown(points, &label, reference, Metric::Rmse, &budgets));
                let _ = writeln!(s);
            }
            if opts.flip {
                let _ = writeln!(s, "FLIP (LDR, exposure 0) against the same reference:\n");
                s.push_str(&report::error_table_markdown(points, &label, reference, Metric::Flip));
                let _ = writeln!(s);
            }
            for o in report::observations(points, &label, reference) {
                let _ = writeln!(s, "- {o}");
            }
            let _ = writeln!(s);
            let _ = writeln!(
                s,
                "![RMSE vs frames](plots/{label}_{reference}_rmse_vs_frames.svg) ![RMSE vs time](plots/{label}_{reference}_rmse_vs_time.svg)\n"
            );
        }
    }
    let _ = writeln!(s, "Raw numbers: `curves.csv` (every checkpoint: frames, GPU ms, wall ms, RMSE, relMSE, FLIP) and `frame_times.csv` (per-pass medians).");
    s
}
